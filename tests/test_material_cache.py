"""Material tables kept across a Renderer's frames (usd/material_cache.py): reused only while
nothing they were read from can change, and every frame looks as a fresh render of it does."""

import numpy as np
from pxr import Gf, Sdf, Usd, UsdGeom, UsdShade

import warp_blur as wb
from scenes import emissive_quad_stage, two_quads_stage
from warp_blur.usd.framing import FRAMING_CAMERA_PATH
from warp_blur.usd.material_cache import shading_is_static

RES = (32, 24)


def _renderer(path: str) -> wb.Renderer:
    return wb.Renderer(path, resolution=RES, settings=wb.RenderSettings(method="analytic", aovs=()))


def _fresh(path: str, frame: float) -> np.ndarray:
    return _renderer(path).render(frame).rgba


def _centre(rgba: np.ndarray) -> np.ndarray:
    return rgba[RES[1] // 2, RES[0] // 2, :3]


def test_a_static_stage_reads_its_materials_once_and_renders_as_fresh(scene_path):
    path = two_quads_stage(scene_path())
    r = _renderer(path)
    frames = (0.75, 1.0, 1.25)
    kept = [r.render(f).rgba for f in frames]
    assert r.materials.reused == len(frames) - 1
    for f, rgba in zip(frames, kept):
        np.testing.assert_array_equal(rgba, _fresh(path, f))


def test_an_animated_material_input_is_read_every_frame(scene_path):
    path = emissive_quad_stage(scene_path(), emissive=(0.9, 0.4, 0.2))
    stage = Usd.Stage.Open(path)
    emit = UsdShade.Shader.Get(stage, "/World/Looks/Emit/PreviewSurface").GetInput("emissiveColor").GetAttr()
    emit.Set(Gf.Vec3f(0.2, 0.8, 0.1), Usd.TimeCode(0.5))
    emit.Set(Gf.Vec3f(0.9, 0.1, 0.7), Usd.TimeCode(1.5))
    stage.GetRootLayer().Save()
    assert not shading_is_static(Usd.Stage.Open(path))
    r = _renderer(path)
    a, b = r.render(0.75).rgba, r.render(1.25).rgba
    assert r.materials.reused == 0
    np.testing.assert_array_equal(a, _fresh(path, 0.75))
    np.testing.assert_array_equal(b, _fresh(path, 1.25))
    assert np.abs(_centre(a) - _centre(b)).max() > 0.05


def test_an_input_connected_to_a_time_sampled_attribute_elsewhere_is_not_static(scene_path):
    path = emissive_quad_stage(scene_path())
    stage = Usd.Stage.Open(path)
    assert shading_is_static(stage)
    holder = stage.DefinePrim("/World/Controls", "Scope")
    colour = holder.CreateAttribute("inputs:tint", Sdf.ValueTypeNames.Color3f)
    colour.Set(Gf.Vec3f(1, 0, 0), Usd.TimeCode(0.5))
    colour.Set(Gf.Vec3f(0, 1, 0), Usd.TimeCode(1.5))
    assert shading_is_static(stage)          # nothing reads it yet
    emit = UsdShade.Shader.Get(stage, "/World/Looks/Emit/PreviewSurface").GetInput("emissiveColor")
    emit.GetAttr().AddConnection(colour.GetPath())
    assert not shading_is_static(stage)


def test_an_edit_between_frames_drops_the_kept_table(scene_path):
    path = emissive_quad_stage(scene_path(), emissive=(0.9, 0.4, 0.2))
    r = _renderer(path)
    before = r.render(1.0).rgba
    r.render(1.0)
    assert r.materials.reused == 1
    emit = UsdShade.Shader.Get(r.stage, "/World/Looks/Emit/PreviewSurface").GetInput("emissiveColor")
    emit.Set(Gf.Vec3f(0.1, 0.3, 0.9))
    after = r.render(1.0).rgba
    assert r.materials.reused == 1           # read again after the edit
    np.testing.assert_allclose(_centre(before), (0.9, 0.4, 0.2), atol=1e-6)
    np.testing.assert_allclose(_centre(after), (0.1, 0.3, 0.9), atol=1e-6)
    r.render(1.0)
    assert r.materials.reused == 2           # and kept again


def test_the_framing_camera_placed_each_frame_keeps_the_table(scene_path):
    path = emissive_quad_stage(scene_path())
    stage = Usd.Stage.Open(path)
    assert stage.RemovePrim("/World/Cam")
    stage.GetRootLayer().Save()
    r = _renderer(path)
    assert str(r.camera.GetPath()) == FRAMING_CAMERA_PATH
    first = r.render(0.75).rgba
    r.render(1.25)
    assert r.materials.reused == 1
    np.testing.assert_array_equal(first, _fresh(path, 0.75))


def test_a_dropped_renderer_frees_its_table_without_a_garbage_collection(scene_path):
    import gc
    import weakref
    path = emissive_quad_stage(scene_path())
    r = _renderer(path)
    r.render(1.0)
    table = weakref.ref(r.materials.table_for(1.0))
    gc.disable()
    try:
        del r
        assert table() is None
    finally:
        gc.enable()


def test_threads_sharing_a_renderer_take_turns_and_get_what_one_thread_gets(scene_path):
    from concurrent.futures import ThreadPoolExecutor
    path = two_quads_stage(scene_path())
    frames = [0.75, 1.0, 1.25, 0.75, 1.0, 1.25]
    serial = {f: _fresh(path, f) for f in set(frames)}
    r = _renderer(path)
    with ThreadPoolExecutor(3) as pool:
        results = list(pool.map(lambda f: r.render(f).rgba, frames))
    for f, rgba in zip(frames, results):
        np.testing.assert_array_equal(rgba, serial[f])
    assert r.materials.reused == len(frames) - 1


def test_an_animated_dome_input_keeps_no_table(scene_path):
    """The kept table's TextureSet holds the dome's map and radiance (dome.dome_map): a dome whose
    inputs change in time would add to it every frame, so the stage does not count as static."""
    path = emissive_quad_stage(scene_path())
    stage = Usd.Stage.Open(path)
    assert shading_is_static(stage)
    dome = stage.GetPrimAtPath("/World/Dome").GetAttribute("inputs:intensity")
    dome.Set(1.0, Usd.TimeCode(0.5))
    dome.Set(2.0, Usd.TimeCode(1.5))
    assert not shading_is_static(stage)
    stage.GetPrimAtPath("/World/Dome").GetAttribute("inputs:intensity").Clear()
    turn = UsdGeom.Xformable(stage.GetPrimAtPath("/World/Dome")).AddRotateYOp()
    turn.Set(10.0, Usd.TimeCode(0.5))
    turn.Set(40.0, Usd.TimeCode(1.5))
    assert shading_is_static(stage)          # a turning dome: its map is the same image
