"""The Python API's frame (api.py): the Z/motion AOVs rendered on a helper beside the method."""

import os
import threading

import numpy as np
import pytest
from conftest import ROOT, SCENES
from scenes import lit_stage

import warp_blur as wb
import warp_blur.api as api

RES = (64, 48)


def _aov_threads() -> list[threading.Thread]:
    return [t for t in threading.enumerate() if t.name == "warp_blur_aovs"]


@pytest.mark.parametrize("method", ["analytic", "stochastic", "accumulation"])
def test_aovs_rendered_beside_the_method_equal_those_rendered_after_it(scene_path, method):
    """On two threads the Z/motion pass runs on a helper while the method renders; on one it runs
    after. The AOVs are the same, the image too, and the frame's bin pairs and dropped back faces
    are the method's own, as without AOVs (the pass used to add its pairs and overwrite the
    back-face count)."""
    path = lit_stage(scene_path())
    beside = wb.render(path, frame=1, resolution=RES, method=method, samples=8, threads=2)
    after = wb.render(path, frame=1, resolution=RES, method=method, samples=8, threads=1)
    alone = wb.render(path, frame=1, resolution=RES, method=method, samples=8, threads=2, aovs=())
    assert np.isfinite(beside.aovs["Z"]).sum() > 100 and np.abs(beside.aovs["motion"]).max() > 1
    for name in ("Z", "motion"):
        np.testing.assert_array_equal(beside.aovs[name], after.aovs[name])
    np.testing.assert_allclose(beside.rgba, after.rgba, atol=1e-6)
    np.testing.assert_array_equal(beside.rgba, alone.rgba)
    for key in ("bin_pairs", "back_faces_dropped"):
        assert beside.stats.get(key) == alone.stats.get(key)
    assert not _aov_threads()


def test_a_failing_method_waits_for_the_aov_helper_and_raises(scene_path, monkeypatch):
    """The method's error reaches the caller, after the helper is done with the frame's buffers."""
    path = lit_stage(scene_path())
    seen = {}
    release = threading.Event()
    depth_motion = api.depth_motion

    def held(ctx, snapshots=None):   # the helper's pass waits until the method has looked
        release.wait(30)
        return depth_motion(ctx, snapshots)

    def failing(ctx):
        seen["helpers"] = len(_aov_threads())
        release.set()
        raise RuntimeError("method failed")
    monkeypatch.setattr(api, "depth_motion", held)
    monkeypatch.setattr(api, "get_method", lambda name: failing)
    with pytest.raises(RuntimeError, match="method failed"):
        wb.render(path, frame=1, resolution=RES, method="analytic", threads=2)
    assert seen["helpers"] == 1   # it was running beside the method
    assert not _aov_threads()


@pytest.mark.parametrize("case", ["lit", "demo_sharp", "cesium_man", "teapot"])
def test_a_still_frame_takes_its_aovs_from_its_own_visibility_pass(scene_path, monkeypatch, case):
    """A frame where nothing moves (a still stage, or a sharp shutter: real assets without one
    render so) writes Z and motion from the pass that renders it (render_sharp_depth_motion)
    instead of binning and rendering the frame again: the image and both AOVs are those of the
    separate pass, bit for bit, and motion is 0."""
    import warp_blur.methods.frame as frame
    real = os.path.join(os.path.dirname(ROOT), "shared", "real_usd")
    paths = {"lit": None, "demo_sharp": os.path.join(SCENES, "demo.usda"),
             "cesium_man": os.path.join(real, "test_assets", "USDZ", "CesiumMan", "CesiumMan.usdz"),
             "teapot": os.path.join(real, "full_assets", "Teapot", "Teapot.usd")}
    path = paths[case] or lit_stage(scene_path(), shutter=(0.0, 0.0))
    if not os.path.exists(path):
        pytest.skip("../shared/real_usd is not beside the checkout")
    r = wb.Renderer(path, resolution=RES, settings=wb.RenderSettings(method="analytic", shutter=(0.0, 0.0)))
    frame_time = r.default_frame()
    one = r.render(frame_time)
    assert one.stats["static_frame"] is True
    monkeypatch.setattr(frame, "STATIC_AOVS_IN_ONE_PASS", False)
    apart = r.render(frame_time)
    assert np.isfinite(one.aovs["Z"]).sum() > 50
    np.testing.assert_array_equal(one.rgba, apart.rgba)
    np.testing.assert_array_equal(one.aovs["Z"], apart.aovs["Z"])
    np.testing.assert_array_equal(one.aovs["motion"], apart.aovs["motion"])
    assert not one.aovs["motion"].any()
    assert "aovs" not in one.stats["time"] and "aovs" in apart.stats["time"]   # no pass of their own
