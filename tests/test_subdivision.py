"""Catmull-Clark refinement of subdivision meshes (issue 19): the stencil follows the scheme's
rules (checked by hand on a cube), refined meshes render rounder than their cage, in every method,
and carry their primvars."""

import numpy as np
import pytest
from pxr import Gf, UsdGeom, Vt

import warp_blur as wb
from warp_blur.usd.subdivision import _one_level, refine

CUBE_POINTS = np.array([(x, y, z) for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], np.float64)
CUBE_FACES = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]]


def test_one_level_on_a_cube_follows_the_rules():
    stencil, quads, _, _, _ = _one_level([np.array(f) for f in CUBE_FACES], 8)
    refined = stencil @ CUBE_POINTS
    assert refined.shape == (8 + 12 + 6, 3) and quads.shape == (24, 4)
    # vertex points: (Q + 2R + (n - 3) P) / n with n = 3 -> 5/9 of each corner
    np.testing.assert_allclose(np.abs(refined[:8]), 5.0 / 9.0)
    # edge points: (a + b + F1 + F2) / 4 -> (0.75, 0.75, 0) up to signs and axes
    np.testing.assert_allclose(np.sort(np.abs(refined[8:20]), axis=1), np.tile([0.0, 0.75, 0.75], (12, 1)))
    # face points: centroids
    np.testing.assert_allclose(np.sort(np.abs(refined[20:]), axis=1), np.tile([0.0, 0.0, 1.0], (6, 1)))
    ref = refine(np.full(6, 4), np.concatenate(CUBE_FACES), 8, 2)
    assert ref.levels == 2 and len(ref.quads) == 96
    assert np.allclose(np.asarray(ref.stencil.sum(axis=1)).ravel(), 1.0)   # affine: rows sum to 1


def _cube_stage(path: str, scheme: str, moving: bool = False) -> str:
    from authoring import add_camera, new_stage
    stage = new_stage(path)
    add_camera(stage)
    mesh = UsdGeom.Mesh.Define(stage, "/World/Cube")
    mesh.CreatePointsAttr(Vt.Vec3fArray([Gf.Vec3f(*p) for p in CUBE_POINTS]))
    mesh.CreateFaceVertexCountsAttr([4] * 6)
    mesh.CreateFaceVertexIndicesAttr([i for f in CUBE_FACES for i in f])
    mesh.CreateSubdivisionSchemeAttr(scheme)
    colors = [Gf.Vec3f(1, 0, 0), Gf.Vec3f(0, 1, 0), Gf.Vec3f(0, 0, 1), Gf.Vec3f(1, 1, 0), Gf.Vec3f(0, 1, 1),
              Gf.Vec3f(1, 0, 1)]
    pv = UsdGeom.PrimvarsAPI(mesh).CreatePrimvar("displayColor", Sdf_color3f(), UsdGeom.Tokens.uniform)
    pv.Set(Vt.Vec3fArray(colors))
    xf = mesh.AddRotateXYZOp()
    if moving:
        xf.Set(Gf.Vec3f(20, 30, 0), 0.5)
        xf.Set(Gf.Vec3f(20, 60, 0), 1.5)
    else:
        xf.Set(Gf.Vec3f(20, 30, 0))
    stage.GetRootLayer().Save()
    return path


def Sdf_color3f():
    from pxr import Sdf
    return Sdf.ValueTypeNames.Color3fArray


def test_a_subdivided_cube_renders_rounder_than_its_cage(scene_path):
    cage = wb.render(_cube_stage(scene_path(), "none"), frame=1, method="velocity", resolution=(64, 48),
                     shadows="off").rgba[..., 3].sum()
    smooth = wb.render(_cube_stage(scene_path(), "catmullClark"), frame=1, method="velocity", resolution=(64, 48),
                       shadows="off").rgba[..., 3].sum()
    # the limit surface lies well inside the cage: through its faces' middles (~0.8 of the way to a
    # face's centre), far from its corners
    assert 0.3 * cage < smooth < 0.8 * cage


@pytest.mark.parametrize("method", ["analytic", "accumulation", "stochastic", "velocity"])
def test_a_moving_subdivided_mesh_renders_in_every_method(scene_path, method):
    from warp_blur.usd.scene import Scene
    from warp_blur.usd.stage import Shutter, choose_camera, open_stage
    path = _cube_stage(scene_path(), "catmullClark", moving=True)
    stage = open_stage(path)
    scene = Scene(stage, choose_camera(stage, None), 1.0, Shutter(0.5, 1.5))
    assert scene.num_triangles == 2 * 96
    # uniform displayColor: every refined triangle keeps its cage face's colour
    assert {tuple(np.round(c, 3)) for c in scene.corner_colors} <= {(1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 0),
                                                                     (0, 1, 1), (1, 0, 1)}
    result = wb.render(path, frame=1, method=method, resolution=(64, 48), samples=4, shadows="off")
    assert np.isfinite(result.rgba).all() and result.rgba[..., 3].max() > 0.9


CUBE_EDGES = sorted({tuple(sorted((f[i], f[(i + 1) % 4]))) for f in CUBE_FACES for i in range(4)})


def _refined_cube(sharpness: float | None = None, corner: float | None = None) -> np.ndarray:
    """The cube's points after two levels, every edge creased with `sharpness` and/or every
    vertex a corner of sharpness `corner`."""
    from warp_blur.usd.subdivision import refine
    creases = {e: sharpness for e in CUBE_EDGES} if sharpness is not None else None
    corners = np.full(8, corner) if corner is not None else None
    ref = refine(np.full(6, 4), np.concatenate(CUBE_FACES), 8, 2, creases, corners)
    return ref.stencil @ CUBE_POINTS


def test_infinitely_sharp_creases_keep_a_cube_a_cube():
    """Every edge creased at sharpness >= the levels: every vertex is a corner (3 creased edges),
    edges stay straight and faces flat, so each refined point lies on the cube's surface."""
    for sharpness in (2.0, 10.0):
        pts = _refined_cube(sharpness)
        np.testing.assert_allclose(np.abs(pts).max(axis=1), 1.0, atol=1e-12)
        np.testing.assert_allclose(np.abs(pts[:8]), 1.0)          # the corners stay put
    smooth = _refined_cube()
    assert np.abs(smooth).max(axis=1).min() < 0.7


def test_edges_still_sharp_at_the_rendered_level_shade_hard():
    """A cube creased beyond the levels (10, 3 > 2) has its points copied per side of each crease,
    so every smooth vertex normal is its own face's normal (flat faces, hard edges); copies of a
    point are the same point; at sharpness 2 the creases end at this level and normals blend."""
    from warp_blur.usd.normals import vertex_normals
    from warp_blur.usd.subdivision import refined_triangles

    def worst_normal(sharpness: float) -> tuple[float, np.ndarray, object]:
        ref = refine(np.full(6, 4), np.concatenate(CUBE_FACES), 8, 2, {e: sharpness for e in CUBE_EDGES})
        pts = ref.stencil @ CUBE_POINTS
        tris = refined_triangles(ref)[0]
        fn = np.cross(pts[tris[:, 1]] - pts[tris[:, 0]], pts[tris[:, 2]] - pts[tris[:, 0]])
        fn /= np.linalg.norm(fn, axis=1, keepdims=True)
        cos = np.einsum("tcj,tj->tc", vertex_normals(pts, tris)[tris], fn)
        return float(np.abs(cos - 1.0).max()), pts, ref

    for sharpness in (10.0, 3.0):
        err, pts, ref = worst_normal(sharpness)
        assert err < 1e-6
        assert len(pts) > 98                                  # points on the creases were copied
        np.testing.assert_allclose(np.abs(pts[:8]), 1.0)      # originals keep their indices
        key = np.round(pts, 12)
        assert len(np.unique(key, axis=0)) == 98              # ... and copies sit exactly on them
    assert worst_normal(2.0)[0] > 0.1


def test_semi_sharp_creases_blend_between_smooth_and_sharp():
    """A corner's refined position moves monotonically from the smooth limit towards the cage
    corner as the creases' sharpness grows (0.5 halfway in the first level's rule)."""
    corner = [float(np.abs(_refined_cube(s)[0]).mean()) for s in (0.0, 0.5, 1.0, 1.5, 2.0)]
    assert all(a < b for a, b in zip(corner, corner[1:]))
    assert corner[-1] == pytest.approx(1.0)
    from warp_blur.usd.subdivision import _one_level
    smooth = _one_level([np.array(f) for f in CUBE_FACES], 8)[0] @ CUBE_POINTS
    half = _one_level([np.array(f) for f in CUBE_FACES], 8, {e: 0.5 for e in CUBE_EDGES})[0] @ CUBE_POINTS
    np.testing.assert_allclose(half[:8], 0.5 * smooth[:8] + 0.5 * CUBE_POINTS)          # corner rule, w = 0.5
    np.testing.assert_allclose(np.sort(np.abs(half[8:20]), axis=1), np.tile([0.0, 0.875, 0.875], (12, 1)))


def test_corner_sharpness_pins_a_vertex_only():
    pts = _refined_cube(corner=10.0)
    np.testing.assert_allclose(np.abs(pts[:8]), 1.0)
    assert np.abs(pts[8:]).max(axis=1).max() < 1.0          # everything else is still smoothed


def test_authored_creases_are_read_per_crease_and_per_edge(tmp_path):
    from pxr import Usd
    from warp_blur.usd.subdivision import crease_tables
    stage = Usd.Stage.CreateInMemory()
    mesh = UsdGeom.Mesh.Define(stage, "/M")
    mesh.CreateCreaseIndicesAttr([0, 1, 3, 4, 5])
    mesh.CreateCreaseLengthsAttr([3, 2])
    mesh.CreateCreaseSharpnessesAttr([2.0, 0.5])              # one per crease
    mesh.CreateCornerIndicesAttr([7])
    mesh.CreateCornerSharpnessesAttr([3.0])
    edges, corners = crease_tables(mesh, Usd.TimeCode(0), 8)
    assert edges == {(0, 1): 2.0, (1, 3): 2.0, (4, 5): 0.5}
    assert corners[7] == 3.0 and corners[:7].max() == 0.0
    mesh.GetCreaseSharpnessesAttr().Set([2.0, 1.0, 0.5])     # one per crease edge
    edges, _ = crease_tables(mesh, Usd.TimeCode(0), 8)
    assert edges == {(0, 1): 2.0, (1, 3): 1.0, (4, 5): 0.5}


def test_the_level_follows_the_meshs_size_on_screen(scene_path):
    """With the image known, a subdivision mesh is refined until its faces are about 4 px across,
    within the stage's budget level: the same cube is level 2 filling a 256-px image, level 1 as a
    speck in a 16-px one; without a projection the budget level holds."""
    from warp_blur.usd.scene import Scene
    from warp_blur.usd.stage import Shutter, choose_camera, open_stage, projection_at
    path = _cube_stage(scene_path(), "catmullClark")
    stage = open_stage(path)
    cam = choose_camera(stage, None)
    tris = {}
    for name, proj in (("none", None), ("big", projection_at(cam, 1.0, (256, 192))),
                       ("speck", projection_at(cam, 1.0, (16, 12)))):
        tris[name] = Scene(stage, cam, 1.0, Shutter(1.0, 1.0), proj=proj).num_triangles
    assert tris["none"] == tris["big"] == 2 * 96        # level 2: 96 quads
    assert tris["speck"] == 2 * 24                       # level 1: 24 quads


def test_a_refinement_is_built_once_for_the_frames_that_share_its_topology(scene_path, monkeypatch):
    """The stencil depends on the topology alone: a second frame (and a second renderer) of the
    same cage reuses it, with the same image; a changed topology is refined afresh."""
    import warp_blur.usd.subdivision as subdivision
    calls = []
    original = subdivision.refine
    monkeypatch.setattr(subdivision, "refine", lambda *a, **k: calls.append(1) or original(*a, **k))
    monkeypatch.setattr(subdivision, "_REFINEMENTS", type(subdivision._REFINEMENTS)())
    path = _cube_stage(scene_path(), "catmullClark", moving=True)
    settings = wb.RenderSettings(method="analytic", aovs=(), shadows="off")
    first = wb.Renderer(path, resolution=(64, 48), settings=settings).render(1.0).rgba
    again = wb.Renderer(path, resolution=(64, 48), settings=settings)
    assert np.array_equal(again.render(1.0).rgba, first) and len(calls) == 1
    again.render(1.25)
    assert len(calls) == 1
    monkeypatch.setattr(subdivision, "_REFINEMENTS", type(subdivision._REFINEMENTS)())
    fresh = wb.Renderer(path, resolution=(64, 48), settings=settings).render(1.0).rgba
    assert np.array_equal(fresh, first) and len(calls) == 2
    from pxr import Usd
    stage = Usd.Stage.Open(path)
    cube = next(UsdGeom.Mesh(p) for p in stage.Traverse() if p.IsA(UsdGeom.Mesh))
    cube.GetFaceVertexIndicesAttr().Set([i for f in CUBE_FACES[::-1] for i in f])   # the faces reordered
    stage.GetRootLayer().Save()
    wb.Renderer(path, resolution=(64, 48), settings=settings).render(1.0)
    assert len(calls) == 3
