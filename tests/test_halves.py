"""The frame's error estimate (methods/halves.py): the frame minus the frame of its even-indexed
instants, samples or time slots, checked against the acceptance references (an independent
renderer's 4096 instants) and against its own arithmetic."""

import os

import numpy as np
import pytest
from conftest import ACCEPTANCE
from scenes import two_quads_stage

import warp_blur as wb
from warp_blur.methods.halves import InstantHalves, rms
from warp_blur.output.files import read_exr
from warp_blur.output.metrics import rmse

ACCEPT_RES = (128, 96)


def test_rms_is_the_root_mean_square():
    d = np.random.default_rng(3).normal(size=(50, 4)).astype(np.float32)
    assert rms(d) == pytest.approx(float(np.sqrt(np.mean(d.astype(np.float64) ** 2))), rel=1e-5)
    assert rms(np.zeros((0, 4), np.float32)) == 0.0


@pytest.mark.parametrize("instants", [2, 3, 4])
def test_instant_halves_sum_to_the_frame_and_estimate_the_even_instants_difference(instants):
    """Instant i adds into target(i); image() is every instant's sum; estimate() is the RMS of the
    frame minus the mean of the even instants alone (their count is (n + 1) // 2), zero at pixels
    named exact."""
    rng = np.random.default_rng(instants)
    values = rng.uniform(size=(instants, 6, 4)).astype(np.float32)   # each instant's image
    halves = InstantHalves(6, instants, "cpu")
    for i in range(instants):
        target = halves.target(i)
        target.assign(target.numpy() + values[i] / instants)
    frame = values.mean(axis=0)
    np.testing.assert_allclose(halves.image(), frame, rtol=1e-6)
    even = values[0::2].mean(axis=0)
    assert halves.estimate() == pytest.approx(float(np.sqrt(np.mean((frame - even) ** 2))), rel=1e-5)
    exact = np.array([1, 4])
    diff = frame - even
    diff[exact] = 0.0
    assert halves.estimate(exact) == pytest.approx(float(np.sqrt(np.mean(diff ** 2))), rel=1e-5)


def test_one_instant_has_no_estimate():
    halves = InstantHalves(4, 1, "cpu")
    assert halves.target(0) is halves.target(1)
    assert halves.estimate() is None


CASES = [dict(method="accumulation", samples=16), dict(method="stochastic", samples=16), dict(method="analytic"),
         dict(method="analytic", time_bits=32)]


@pytest.mark.parametrize("name", ["diagonal", "spin_edge_on", "occluder_pass", "dolly"])
def test_estimate_is_within_a_small_factor_of_the_true_error(name):
    """Against the acceptance references each method's estimate lies between half and four times
    its RMSE (measured 1.2-2.8x on these frames; 0.8-3.8x on the bench scenes)."""
    ref = read_exr(os.path.join(ACCEPTANCE, "refs", f"{name}.exr"))["RGBA"]
    for kw in CASES:
        r = wb.render(os.path.join(ACCEPTANCE, "scenes", f"{name}.usda"), frame=1, resolution=ACCEPT_RES, aovs=(),
                      **kw)
        actual = rmse(r.rgba, ref)
        estimate = r.stats["error_estimate"]
        assert 0.5 * actual <= estimate <= 4.0 * actual, (kw, actual, estimate)
        assert r.metadata["error_estimate"] == estimate   # the EXR header's warp_blur.error_estimate


@pytest.mark.parametrize("kw, more", [(dict(method="accumulation", samples=16), dict(samples=64)),
                                      (dict(method="stochastic", samples=16), dict(samples=64)),
                                      (dict(method="analytic", time_bits=32), dict(time_bits=128))])
def test_estimate_falls_as_the_error_does(kw, more):
    """Four times the instants, samples or time bits: about a quarter of the estimate (error ∝ 1/N
    on blurred edges)."""
    path = os.path.join(ACCEPTANCE, "scenes", "diagonal.usda")
    coarse = wb.render(path, frame=1, resolution=ACCEPT_RES, aovs=(), **kw).stats["error_estimate"]
    fine = wb.render(path, frame=1, resolution=ACCEPT_RES, aovs=(), **{**kw, **more}).stats["error_estimate"]
    assert 0.15 * coarse < fine < 0.4 * coarse


def test_frames_without_an_estimate_or_without_error(scene_path):
    """Velocity blur and analytic's exact spans report none (None); one instant of a real shutter
    neither; a sharp shutter has no time to sample (0), the same frame blurred has an estimate."""
    path = two_quads_stage(scene_path())
    kw = dict(frame=1, resolution=(64, 48), aovs=())
    assert wb.render(path, method="velocity", **kw).stats["error_estimate"] is None
    assert wb.render(path, method="analytic", time_bits=0, **kw).stats["error_estimate"] is None
    assert wb.render(path, method="accumulation", samples=1, **kw).stats["error_estimate"] is None
    assert wb.render(path, method="stochastic", samples=1, **kw).stats["error_estimate"] is None
    for method in ("accumulation", "stochastic", "analytic"):
        assert wb.render(path, method=method, shutter=(0.0, 0.0), **kw).stats["error_estimate"] == 0.0
        moving = wb.render(path, method=method, **kw).stats["error_estimate"]
        assert moving > 0.001, (method, moving)


def test_accumulation_estimate_leaves_out_pixels_shaded_whole(scene_path, monkeypatch):
    """Still tiles added once at full weight (the same at every instant) count as exact: the
    estimate equals the one of rendering every pixel at every instant, where their even and odd
    halves are alike."""
    from scenes import shadow_stage
    import warp_blur.methods.accumulation as accumulation
    path = shadow_stage(scene_path(), shadows=False, occluder_samples={0.5: (-1.0, 1.0, 0.0), 1.5: (1.0, 1.0, 0.0)})
    kw = dict(frame=1, resolution=(128, 96), samples=16, aovs=())
    once = wb.render(path, **kw)
    assert once.stats["accumulation_still_shading"] == "once"
    monkeypatch.setattr(accumulation, "STATIC_TILES", False)
    every = wb.render(path, **kw)
    assert "accumulation_still_pixels" not in every.stats
    assert once.stats["error_estimate"] > 0.001
    assert once.stats["error_estimate"] == pytest.approx(every.stats["error_estimate"], rel=1e-3)
