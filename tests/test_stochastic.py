"""Stochastic rasterization: converges to the analytic (exact) image faster than 1/sqrt(N),
deterministic per seed, matches the acceptance references at 16 samples."""

import os

import numpy as np
import pytest
from conftest import ACCEPTANCE, bin_in_entry_order
from scenes import two_quads_stage

import warp_blur as wb
from warp_blur.core.errors import SettingsError
from warp_blur.output.metrics import rmse
from warp_blur.output.files import read_exr

RES = (64, 48)


def test_converges_faster_than_random_sampling(scene_path):
    path = two_quads_stage(scene_path())
    ref = wb.render(path, frame=1, resolution=RES, method="analytic", time_bits=0, aovs=())
    err = {n: rmse(wb.render(path, frame=1, resolution=RES, method="stochastic", samples=n, aovs=()).rgba, ref.rgba)
           for n in (4, 16, 64)}
    # random sampling halves the error per 4× samples; stratified does better
    assert err[16] < err[4] / 2.5 and err[64] < err[16] / 2.5, err


def test_same_seed_same_image_other_seed_other_noise(scene_path):
    path = two_quads_stage(scene_path())
    a = wb.render(path, frame=1, resolution=RES, method="stochastic", samples=8, seed=3, aovs=())
    b = wb.render(path, frame=1, resolution=RES, method="stochastic", samples=8, seed=3, aovs=(), threads=1)
    c = wb.render(path, frame=1, resolution=RES, method="stochastic", samples=8, seed=4, aovs=())
    np.testing.assert_array_equal(a.rgba, b.rgba)
    assert not np.array_equal(a.rgba, c.rgba)


def test_static_scene_is_exact(scene_path):
    from scenes import emissive_quad_stage
    path = emissive_quad_stage(scene_path(), with_light=True)
    sharp = wb.render(path, frame=1, resolution=RES, samples=1, aovs=())
    st = wb.render(path, frame=1, resolution=RES, method="stochastic", samples=4, aovs=())
    np.testing.assert_allclose(st.rgba, sharp.rgba, atol=1e-6)


def test_seed_with_another_method_is_an_error():
    with pytest.raises(SettingsError):
        wb.RenderSettings(method="analytic", seed=1)


@pytest.mark.parametrize("name", ["diagonal", "spin_edge_on", "occluder_pass", "dolly"])
def test_acceptance_reference(name):
    ref = read_exr(os.path.join(ACCEPTANCE, "refs", f"{name}.exr"))["RGBA"]
    r = wb.render(os.path.join(ACCEPTANCE, "scenes", f"{name}.usda"), frame=1, resolution=(128, 96),
                  method="stochastic", samples=16, aovs=())
    assert rmse(r.rgba, ref) <= 0.03


def test_static_pixels_take_the_exact_expectation_under_a_moving_shadow(scene_path):
    """Where no sample sees a moving triangle and the lights hold still, the pixel is shaded once
    with the samples' exact expectation: the same for every seed, equal to the analytic method's
    static pixels, a moving shadow's time average included. The occluder passes above the
    camera's view, so every pixel sees only still geometry."""
    from scenes import shadow_stage
    path = shadow_stage(scene_path(), occluder_samples={0.5: (-1.0, 6.0, 0.0), 1.5: (1.0, 6.0, 0.0)})
    kw = dict(frame=1, resolution=(96, 72), aovs=(), shadows="direct", shadow_map_size=256)
    a = wb.render(path, method="stochastic", samples=8, seed=1, **kw).rgba
    b = wb.render(path, method="stochastic", samples=8, seed=2, **kw).rgba
    exact = wb.render(path, method="analytic", **kw).rgba
    np.testing.assert_array_equal(a, b)
    assert np.abs(a - exact).max() < 1e-5
    lum = a[..., :3].mean(axis=-1)
    lit = np.median(lum[a[..., 3] == 1.0])
    # the moving shadow is there, as a time average (darker than lit, lighter than the umbra)
    assert ((lum < 0.9 * lit) & (lum > 0.1 * lit) & (a[..., 3] == 1.0)).sum() > 20


def test_still_entries_shaded_once_a_pixel_equal_shading_every_sample(scene_path, monkeypatch):
    """Nothing moves and translucent layers make the samples differ: under still lights and a
    shadow map of one instant, a still entry's radiance is the same at every sample, so it is
    shaded once a pixel and reused; the image equals shading every sample, bit for bit."""
    from scenes import translucent_layers_stage
    import warp_blur.methods.stochastic as stochastic
    path = translucent_layers_stage(scene_path())
    kw = dict(frame=1, method="stochastic", samples=16, resolution=(96, 72), aovs=(), shadow_map_size=256)
    kept = wb.render(path, **kw)
    assert kept.stats["stochastic_still_radiance_kept"] is True
    monkeypatch.setattr(stochastic, "KEEP_STILL_RADIANCE", False)
    every = wb.render(path, **kw)
    assert every.stats["stochastic_still_radiance_kept"] is False
    np.testing.assert_array_equal(kept.rgba, every.rgba)
    # the translucent layers are there, partly (a pixel's samples differ)
    assert np.abs(kept.rgba - wb.render(path, **kw, shadows="off").rgba).max() > 0.05


def test_nearest_first_walk_stops_early_and_changes_no_sample(scene_path, monkeypatch):
    """The moving walk stops at the first entry wholly beyond every sample's hit (and the static
    surface): the image equals that of lists in entry order walked to the end, on steeply and
    slightly tilted interpenetrating layers with a coplanar pair in front (scenes.tilted_layers_stage)."""
    from scenes import tilted_layers_stage
    path = tilted_layers_stage(scene_path())
    kw = dict(frame=1, resolution=(96, 72), method="stochastic", samples=8, shadows="off")
    nearest_first = wb.render(path, **kw)
    bin_in_entry_order(monkeypatch)
    walked = wb.render(path, **kw)
    assert nearest_first.rgba[..., 3].mean() > 0.05
    np.testing.assert_array_equal(nearest_first.rgba, walked.rgba)
