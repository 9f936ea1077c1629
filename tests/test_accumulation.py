"""Accumulation: N=1 is the sharp render at the shutter centre; acceptance references match."""

import os

import numpy as np
import pytest
from conftest import ACCEPTANCE
from scenes import two_quads_stage

import warp_blur as wb
from warp_blur.output.metrics import rmse
from warp_blur.methods.accumulation import instants
from warp_blur.output.files import read_exr

ACCEPT_SCENES = ["diagonal", "spin_edge_on", "occluder_pass", "dolly"]


def test_instants_follow_the_spec():
    np.testing.assert_allclose(instants(4), [0.125, 0.375, 0.625, 0.875])


def test_one_instant_equals_sharp_render_at_shutter_centre(scene_path):
    path = two_quads_stage(scene_path())
    acc = wb.render(path, frame=1, resolution=(64, 48), samples=1)
    sharp = wb.render(path, frame=1, resolution=(64, 48), samples=7, shutter=(0.0, 0.0))
    np.testing.assert_array_equal(acc.rgba, sharp.rgba)


def test_more_instants_blur(scene_path):
    path = two_quads_stage(scene_path())
    a = wb.render(path, frame=1, resolution=(64, 48), samples=32)
    alpha = a.rgba[..., 3]
    assert ((alpha > 0.05) & (alpha < 0.95)).sum() > 200


def test_negative_shutter_is_black(scene_path):
    path = two_quads_stage(scene_path())
    r = wb.render(path, frame=1, resolution=(32, 24), samples=4, shutter=(0.5, -0.5))
    assert not r.rgba.any()
    # the AOVs asked for are there too, as where nothing is seen: Z inf, motion 0 (a fuzz soak
    # found them missing from the EXR of such a frame)
    assert set(r.aovs) == {"Z", "motion"}
    assert np.isposinf(r.aovs["Z"]).all() and r.aovs["Z"].shape == (24, 32)
    assert not r.aovs["motion"].any() and r.aovs["motion"].shape == (24, 32, 2)


@pytest.mark.parametrize("name", ACCEPT_SCENES)
def test_acceptance_reference(name):
    ref_path = os.path.join(ACCEPTANCE, "refs", f"{name}.exr")
    assert os.path.exists(ref_path), f"missing acceptance reference {ref_path}"
    ref = read_exr(ref_path)["RGBA"]
    r = wb.render(os.path.join(ACCEPTANCE, "scenes", f"{name}.usda"), frame=1, resolution=(128, 96),
                  method="accumulation", samples=128)
    assert rmse(r.rgba, ref) <= 0.002


@pytest.mark.parametrize("spatial", [1, 2])
def test_still_tiles_rendered_once_equal_every_instant(scene_path, monkeypatch, spatial):
    """Under still lights and no shadow maps, tiles no moving triangle touches at any instant are
    rendered once; the image equals rendering every pixel at every instant."""
    from scenes import shadow_stage
    import warp_blur.methods.accumulation as accumulation
    # a lit ground under a light that casts no shadow, and a dark square crossing above it
    path = shadow_stage(scene_path(), shadows=False, occluder_samples={0.5: (-1.0, 1.0, 0.0), 1.5: (1.0, 1.0, 0.0)})
    kw = dict(frame=1, resolution=(128, 96), samples=16, aovs=(), spatial_samples=spatial)
    once = wb.render(path, **kw)
    assert 0.2 < once.stats["accumulation_still_pixels"] < 0.9
    assert once.stats["accumulation_moving_tiles"] == "changing triangles"
    monkeypatch.setattr(accumulation, "STATIC_TILES", False)
    every = wb.render(path, **kw)
    assert "accumulation_still_pixels" not in every.stats
    assert np.abs(once.rgba - every.rgba).max() < 1e-6
    sharp = wb.render(path, frame=1, resolution=(128, 96), samples=1, aovs=(), spatial_samples=spatial)
    assert rmse(once.rgba, sharp.rgba) > 0.01   # there is blur


@pytest.mark.parametrize("case", ["moving_shadow_direct", "moving_shadow_warped", "moving_light"])
def test_still_tiles_reshaded_per_instant_equal_every_instant(scene_path, monkeypatch, case):
    """Where shadows or lights change, still tiles find their surfaces once and are shaded at
    every instant with that instant's lights and shadow maps: equal to rendering every pixel."""
    from scenes import shadow_stage
    import warp_blur.methods.accumulation as accumulation
    mover = {0.5: (-1.0, 1.0, 0.0), 1.5: (1.0, 1.0, 0.0)}
    kw = dict(frame=1, resolution=(96, 72), samples=12, aovs=(), shadow_map_size=256)
    if case == "moving_light":
        path = shadow_stage(scene_path(), light="sphere", light_size=0.2, occluder_samples=mover,
                            light_samples={0.5: (-0.5, 3, 0), 1.5: (0.5, 3, 0)})
        kw["shadows"] = "direct"
    else:
        path = shadow_stage(scene_path(), occluder_samples=mover)
        kw["shadows"] = "direct" if case.endswith("direct") else "warped"
    once = wb.render(path, **kw)
    assert once.stats["accumulation_still_shading"] == "per instant"
    assert once.stats["accumulation_moving_tiles"] == "changing triangles"
    assert 0.2 < once.stats["accumulation_still_pixels"] < 0.95
    monkeypatch.setattr(accumulation, "STATIC_TILES", False)
    every = wb.render(path, **kw)
    assert np.abs(once.rgba - every.rgba).max() < 1e-5


def test_still_tiles_under_shadows_that_never_change_render_once(scene_path, monkeypatch):
    """Nothing moves, so the light's shadow map is the same at every instant, but a translucent
    (fractional opacity) occluder makes every instant differ where it is: the other tiles look the
    same at every instant, shadow included, and are rendered once, equal to every instant."""
    from pxr import Sdf, Usd, UsdShade
    from scenes import shadow_stage
    import warp_blur.methods.accumulation as accumulation
    path = shadow_stage(scene_path())
    stage = Usd.Stage.Open(path)
    surface = UsdShade.Shader.Get(stage, "/World/Looks/Dark/PreviewSurface")
    surface.GetInput("opacity").Set(0.5)
    surface.CreateInput("opacityThreshold", Sdf.ValueTypeNames.Float).Set(0.0)
    stage.GetRootLayer().Save()
    kw = dict(frame=1, resolution=(96, 72), samples=12, aovs=(), shadow_map_size=256)
    once = wb.render(path, **kw)
    assert once.stats["accumulation_still_shading"] == "once"
    assert once.stats["shadow_maps_rendered"] == 1
    assert 0.5 < once.stats["accumulation_still_pixels"] < 0.98
    monkeypatch.setattr(accumulation, "STATIC_TILES", False)
    every = wb.render(path, **kw)
    assert np.abs(once.rgba - every.rgba).max() < 1e-5
    unshadowed = wb.render(path, shadows="off", **kw)
    assert np.abs(once.rgba - unshadowed.rgba).max() > 0.05    # the occluder's shadow is there


@pytest.mark.parametrize("spatial", [1, 2])
def test_instants_differing_only_in_presence_render_in_one_pass(scene_path, monkeypatch, spatial):
    """Nothing moves and only fractional opacity makes the instants differ: the moving tiles'
    instants are one pass that shades each translucent surface a sub-sample shows once (three
    layers overlap: more than the two radiances it remembers). The image is the one of a pass per
    instant, bit for bit, and of every pixel rendered at every instant."""
    from scenes import translucent_layers_stage
    import warp_blur.methods.accumulation as accumulation
    path = translucent_layers_stage(scene_path())
    kw = dict(frame=1, resolution=(96, 72), samples=12, aovs=(), shadow_map_size=256, spatial_samples=spatial)
    one = wb.render(path, **kw)
    assert one.stats["accumulation_presence_pass"] is True
    assert one.stats["accumulation_still_shading"] == "once"
    monkeypatch.setattr(accumulation, "INSTANTS_IN_ONE_PASS", False)
    per_instant = wb.render(path, **kw)
    assert "accumulation_presence_pass" not in per_instant.stats
    np.testing.assert_array_equal(one.rgba, per_instant.rgba)
    monkeypatch.setattr(accumulation, "STATIC_TILES", False)
    every = wb.render(path, **kw)
    assert np.abs(one.rgba - every.rgba).max() < 1e-5
    # the layers are translucent: partly there, over the lit and shadowed ground
    opaque = wb.render(path, **kw, shadows="off")
    assert np.abs(one.rgba - opaque.rgba).max() > 0.05


@pytest.mark.parametrize("shadows", ["off", "direct"])
def test_moving_tiles_rasterise_only_the_triangles_that_change(scene_path, monkeypatch, shadows):
    """Where something moves, the still triangles' nearest hit is found once (and shaded once
    under steady shading) and only the changing triangles are rasterised per instant: the same
    image as rasterising every triangle there at every instant, with a translucent quad lying on
    the still ground (equal depths: the lower triangle index shows, as in a full pass) and 2×2
    sub-samples."""
    from pxr import Sdf, Usd, UsdShade
    from authoring import add_material, add_mesh
    from scenes import shadow_stage
    import warp_blur.methods.accumulation as accumulation
    path = shadow_stage(scene_path(), occluder_samples={0.5: (-1.0, 1.0, 0.0), 1.5: (1.0, 1.0, 0.0)})
    stage = Usd.Stage.Open(path)
    glass = add_material(stage, "/World/Looks/Glass", diffuse=(0.2, 0.3, 0.9), roughness=0.5)
    surface = UsdShade.Shader.Get(stage, "/World/Looks/Glass/PreviewSurface")
    surface.CreateInput("opacity", Sdf.ValueTypeNames.Float).Set(0.5)
    surface.CreateInput("opacityThreshold", Sdf.ValueTypeNames.Float).Set(0.0)
    add_mesh(stage, "/World/Decal", [(-1.0, 0, 1.0), (1.0, 0, 1.0), (1.0, 0, -1.0), (-1.0, 0, -1.0)], [4],
             [0, 1, 2, 3], material=glass)
    stage.GetRootLayer().Save()
    kw = dict(frame=1, resolution=(96, 72), samples=8, aovs=(), shadow_map_size=256, shadows=shadows,
              spatial_samples=2)
    split = wb.render(path, **kw)
    assert split.stats["accumulation_moving_tiles"] == "changing triangles"
    assert split.stats["accumulation_still_shading"] == ("once" if shadows == "off" else "per instant")
    monkeypatch.setattr(accumulation, "MOVING_SPLIT", False)
    full = wb.render(path, **kw)
    assert full.stats["accumulation_moving_tiles"] == "every triangle"
    assert np.abs(split.rgba - full.rgba).max() < 1e-6
    # the decal shows (half the instants) where the occluder is not in front of it
    plain = wb.render(shadow_stage(scene_path(), occluder_samples={0.5: (-1.0, 1.0, 0.0), 1.5: (1.0, 1.0, 0.0)}),
                      **kw)
    assert np.abs(split.rgba - plain.rgba).max() > 0.05


@pytest.mark.parametrize("spatial", [1, 2])
def test_still_pixels_whose_shadows_never_change_are_shaded_once(scene_path, monkeypatch, spatial):
    """A still camera, ground and light, and an occluder crossing above: its shadow moves, so
    the still tiles are reshaded per instant, except the pixels whose shadow lookups read only
    texels that are the same in every map instant: those are shaded once, whole. The image
    equals reshading every still pixel at every instant, and rendering every pixel."""
    from scenes import shadow_stage
    import warp_blur.methods.accumulation as accumulation
    path = shadow_stage(scene_path(), occluder_samples={0.5: (-1.0, 1.0, 0.0), 1.5: (1.0, 1.0, 0.0)})
    kw = dict(frame=1, resolution=(96, 72), samples=16, aovs=(), shadow_map_size=256, spatial_samples=spatial)
    once = wb.render(path, **kw)
    assert once.stats["accumulation_still_shading"] == "per instant"
    assert 0.3 < once.stats["accumulation_steady_pixels"] < 0.99
    monkeypatch.setattr(accumulation, "STEADY_PIXELS", False)
    reshaded = wb.render(path, **kw)
    assert "accumulation_steady_pixels" not in reshaded.stats
    assert np.abs(once.rgba - reshaded.rgba).max() < 1e-5
    monkeypatch.setattr(accumulation, "STATIC_TILES", False)
    every = wb.render(path, **kw)
    assert np.abs(once.rgba - every.rgba).max() < 1e-5
    # the moving shadow is there (its pixels were reshaded)
    assert np.abs(once.rgba - wb.render(path, shadows="off", **kw).rgba).max() > 0.05


def test_recorded_hits_stay_within_the_memory_budget(scene_path):
    from scenes import shadow_stage
    path = shadow_stage(scene_path(), occluder_samples={0.5: (-1.0, 1.0, 0.0), 1.5: (1.0, 1.0, 0.0)})
    kw = dict(frame=1, resolution=(96, 72), samples=8, aovs=(), shadow_map_size=256, shadows="direct")
    small = wb.render(path, memory_budget_mb=0.01, **kw)     # 96×72 hits need ~0.1 MB
    assert "accumulation_still_pixels" not in small.stats
    assert np.abs(small.rgba - wb.render(path, **kw).rgba).max() < 1e-5


def test_nothing_still_renders_every_instant(scene_path):
    path = two_quads_stage(scene_path())
    r = wb.render(path, frame=1, resolution=(64, 48), samples=8, aovs=())
    assert "accumulation_still_pixels" not in r.stats
