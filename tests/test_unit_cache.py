"""Geometry units kept across a Renderer's frames (usd/unit_cache.py): every frame must be the
image a fresh read of the stage gives, whatever is kept; only prims whose unit cannot change are
kept; an edit to the stage between frames drops what was kept."""

import numpy as np
from pxr import Gf, UsdGeom, Vt

import warp_blur as wb
from warp_blur.usd.stage import open_stage
from warp_blur.usd.unit_cache import keepable

RES = (64, 48)
KW = dict(method="analytic", aovs=())


def _set_stage(path: str) -> str:
    """Still props, and one prim of each kind that must be read every frame."""
    from authoring import add_camera, add_distant_light, add_dome, add_mesh, add_quad, new_stage
    stage = new_stage(path, end=4)
    add_camera(stage, translate_samples={0: (0, 0, 10), 4: (0.4, 0.2, 9.5)}, shutter=(-0.25, 0.25))
    add_dome(stage)
    add_distant_light(stage, "/World/Sun", intensity=2.0)
    for i in range(5):   # still props: kept
        add_quad(stage, f"/World/Set/P{i}", 0.4, 0.3, color=(0.2 * i, 0.5, 0.8 - 0.1 * i), translate=(i - 2.0, 1.2, -1))
    arm = UsdGeom.Xform.Define(stage, "/World/Arm")   # an animated parent: its child is kept all the same
    arm.AddRotateZOp().Set(0.0, 0.0)
    arm.GetPrim().GetAttribute("xformOp:rotateZ").Set(60.0, 4.0)
    add_quad(stage, "/World/Arm/Hand", 0.5, 0.3, color=(0.9, 0.3, 0.1), translate=(1.0, -1.0, 0))
    UsdGeom.Sphere.Define(stage, "/World/Ball").AddTranslateOp().Set(Gf.Vec3d(-2, -1, 0))   # a gprim: kept
    blink = add_quad(stage, "/World/Blink", 0.4, 0.4, translate=(0, -1.5, 0.5))    # animated colour: read
    blink.GetDisplayColorAttr().Set(Vt.Vec3fArray([Gf.Vec3f(1, 0, 0)]), 0.0)
    blink.GetDisplayColorAttr().Set(Vt.Vec3fArray([Gf.Vec3f(0, 0, 1)]), 4.0)
    quad = [(-0.3, -0.3, 0), (0.3, -0.3, 0), (0.3, 0.3, 0), (-0.3, 0.3, 0)]
    add_mesh(stage, "/World/Cloth", quad, [4], [0, 1, 2, 3], translate=(2, -1, 0),   # deforming: read
             points_samples={0: quad, 4: [(x * 2, y, z + 0.5) for x, y, z in quad]})
    stage.GetRootLayer().Save()
    return path


READ_EVERY_FRAME = {"/World/Blink", "/World/Cloth"}


def test_keepable_tells_the_prims_whose_unit_cannot_change(scene_path):
    stage = open_stage(_set_stage(scene_path()))
    verdicts = {str(p.GetPath()): keepable(p) for p in stage.Traverse() if p.IsA(UsdGeom.Gprim)}
    assert {path for path, keep in verdicts.items() if not keep} == READ_EVERY_FRAME
    assert len(verdicts) == 9


def test_kept_units_render_every_frame_as_a_fresh_read(scene_path):
    """A Renderer's frames 1..3 (kept units from frame 2 on) equal renders that read the stage
    afresh, bit for bit, with accumulation too (it places every prim at every instant)."""
    path = _set_stage(scene_path())
    for method in ("analytic", "accumulation"):
        kw = dict(KW, method=method, samples=8) if method == "accumulation" else KW
        r = wb.Renderer(path, resolution=RES, settings=wb.RenderSettings(**kw))
        for frame in (1.0, 2.0, 3.0):
            out = r.render(frame)
            fresh = wb.render(path, frame=frame, resolution=RES, **kw)
            assert fresh.stats["prims_reused"] == 0
            assert out.stats["prims_reused"] == (0 if frame == 1.0 else 7)
            np.testing.assert_array_equal(out.rgba, fresh.rgba)


def test_an_edit_between_frames_is_seen(scene_path):
    """A pipeline tool may edit the Renderer's stage between frames: here a kept prop's colour
    gets time samples. The next frame reads every prim again, and from then on the prop, whose
    colour now changes over time, is read every frame: each frame equals a fresh render of the
    edited stage."""
    path = _set_stage(scene_path())
    r = wb.Renderer(path, resolution=RES, settings=wb.RenderSettings(**KW))
    r.render(1.0)
    before = r.render(2.0)
    colour = UsdGeom.Mesh(r.stage.GetPrimAtPath("/World/Set/P2")).GetDisplayColorAttr()
    colour.Set(Vt.Vec3fArray([Gf.Vec3f(0, 1, 0)]), 0.0)
    colour.Set(Vt.Vec3fArray([Gf.Vec3f(1, 0, 1)]), 4.0)
    copy = scene_path("edited")
    r.stage.GetRootLayer().Export(copy)
    for frame, reused in ((2.0, 0), (3.0, 6)):
        out = r.render(frame)
        assert out.stats["prims_reused"] == reused
        np.testing.assert_array_equal(out.rgba, wb.render(copy, frame=frame, resolution=RES, **KW).rgba)
        if frame == 2.0:
            assert not np.array_equal(out.rgba, before.rgba)


def test_a_stage_without_a_camera_keeps_its_units_and_rows(tmp_path):
    """The framing camera the renderer places in a camera-less stage each frame is no edit. Where
    every unit of a frame was kept, the per-triangle rows gathered from them are kept too (frame 3
    on); an edit drops both: every frame equals a fresh render of the stage as it then is."""
    from authoring import add_quad, new_stage
    path = str(tmp_path / "nocam.usda")
    stage = new_stage(path, end=4)
    for i in range(3):
        add_quad(stage, f"/World/P{i}", 0.5, 0.5, translate=(i, 0, 0), color=(0.3 * i, 0.4, 0.5))
    add_quad(stage, "/World/Mover", 0.5, 0.5, translate_samples={0: (0, 1, 0), 4: (1, 1, 0)})
    stage.GetRootLayer().Save()
    kw = dict(resolution=RES, shutter=(-0.25, 0.25), **KW)
    r = wb.Renderer(path, resolution=RES, settings=wb.RenderSettings(shutter=(-0.25, 0.25), **KW))
    for frame in (1.0, 2.0, 3.0):
        out = r.render(frame)
        assert out.stats["prims_reused"] == (0 if frame == 1.0 else 4)
        np.testing.assert_array_equal(out.rgba, wb.render(path, frame=frame, **kw).rgba)
    assert r.units.rows_reused == 1   # frame 3
    points = UsdGeom.Mesh(r.stage.GetPrimAtPath("/World/P1")).GetPointsAttr()
    points.Set(Vt.Vec3fArray([Gf.Vec3f(-0.9, -0.5, 0), Gf.Vec3f(0.5, -0.5, 0), Gf.Vec3f(0.5, 0.9, 0),
                              Gf.Vec3f(-0.5, 0.5, 0)]))
    copy = str(tmp_path / "edited.usda")
    r.stage.GetRootLayer().Export(copy)
    for frame in (3.0, 4.0):
        out = r.render(frame)
        assert out.stats["prims_reused"] == (0 if frame == 3.0 else 4)
        np.testing.assert_array_equal(out.rgba, wb.render(copy, frame=frame, **kw).rgba)
    assert r.units.rows_reused == 1   # frame 3 read again, frame 4 gathered the rows anew


def test_a_subdivision_mesh_is_kept_per_level(scene_path):
    """A Catmull-Clark mesh is read at the level its size on screen needs: a camera dollying in
    asks for more levels over the frames. Its unit is kept while the level holds and read again
    when it changes; every frame equals a fresh read."""
    from authoring import add_camera, add_mesh, new_stage
    path = scene_path()
    stage = new_stage(path, end=6)
    add_camera(stage, translate_samples={0: (0, 0, 60), 6: (0, 0, 4)}, shutter=(-0.25, 0.25))
    cube = [(-1, -1, -1), (1, -1, -1), (1, 1, -1), (-1, 1, -1), (-1, -1, 1), (1, -1, 1), (1, 1, 1), (-1, 1, 1)]
    faces = [0, 3, 2, 1, 4, 5, 6, 7, 0, 1, 5, 4, 2, 3, 7, 6, 1, 2, 6, 5, 0, 4, 7, 3]
    mesh = add_mesh(stage, "/World/Blob", cube, [4] * 6, faces, color=(0.8, 0.5, 0.2))
    mesh.GetSubdivisionSchemeAttr().Set(UsdGeom.Tokens.catmullClark)
    stage.GetRootLayer().Save()
    res = (160, 120)
    r = wb.Renderer(path, resolution=res, settings=wb.RenderSettings(**KW))
    reused, triangles = [], set()
    for frame in (1.0, 2.0, 3.0, 4.0, 5.0, 5.0):
        out = r.render(frame)
        reused.append(out.stats["prims_reused"])
        triangles.add(out.stats["triangles"])
        np.testing.assert_array_equal(out.rgba, wb.render(path, frame=frame, resolution=res, **KW).rgba)
    assert len(triangles) > 1 and reused[-1] == 1   # levels changed; the same frame again keeps it
    assert 0 in reused[1:]                          # a new level is read again
