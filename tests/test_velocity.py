"""Velocity-buffer blur: exact on static scenes, velocity AOV equals the true screen motion (object
and camera, the latter reconstructed from depth), better than the sharp image on the references."""

import os

import numpy as np
import pytest
from conftest import ACCEPTANCE
from scenes import emissive_quad_stage, lit_stage

import warp_blur as wb
from warp_blur.output.metrics import rmse
from warp_blur.output.files import read_exr

RES = (64, 48)


def test_static_scene_is_exactly_the_sharp_image(scene_path):
    path = emissive_quad_stage(scene_path(), with_light=True)
    sharp = wb.render(path, frame=1, resolution=RES, samples=1)
    vel = wb.render(path, frame=1, resolution=RES, method="velocity")
    np.testing.assert_array_equal(vel.rgba, sharp.rgba)
    assert not vel.aovs["motion"].any()
    assert vel.stats["static_frame"] is True  # no velocity work at all


def test_translating_quad_velocity_equals_its_screen_motion(scene_path):
    # 2 units along x at depth 10 over the shutter: 2 / (0.5 * 10 * 2) * 64 px = 12.8 px
    path = emissive_quad_stage(scene_path(), translate_samples={0.5: (-1, 0, 0), 1.5: (1, 0, 0)})
    r = wb.render(path, frame=1, resolution=RES, method="velocity")
    covered = np.isfinite(r.aovs["Z"])
    assert covered.sum() > 100
    np.testing.assert_allclose(r.aovs["motion"][covered], np.tile([12.8, 0.0], (covered.sum(), 1)), atol=1e-3)


def test_camera_translation_velocity_from_depth(scene_path):
    # camera moves +1.5 in x: a static point at depth 10 moves -1.5/(10) * (64 / 1.0) px = -9.6 px
    path = emissive_quad_stage(scene_path(), half=3.0,
                               camera={"translate_samples": {0.5: (-0.75, 0, 10), 1.5: (0.75, 0, 10)}})
    r = wb.render(path, frame=1, resolution=RES, method="velocity")
    covered = np.isfinite(r.aovs["Z"])
    assert r.stats["camera_motion"] is True
    np.testing.assert_allclose(r.aovs["motion"][covered], np.tile([-9.6, 0.0], (covered.sum(), 1)), atol=1e-3)
    # the exact per-vertex motion (used by the other methods) agrees
    acc = wb.render(path, frame=1, resolution=RES, samples=1)
    np.testing.assert_allclose(acc.aovs["motion"][covered], r.aovs["motion"][covered], atol=1e-3)


def test_blur_spreads_past_the_silhouette_and_keeps_energy(scene_path):
    path = emissive_quad_stage(scene_path(), translate_samples={0.5: (-1.5, 0, 0), 1.5: (1.5, 0, 0)})
    sharp = wb.render(path, frame=1, resolution=RES, samples=1, aovs=())
    vel = wb.render(path, frame=1, resolution=RES, method="velocity", aovs=())
    ref = wb.render(path, frame=1, resolution=RES, samples=256, aovs=())
    partial = (vel.rgba[..., 3] > 0.05) & (vel.rgba[..., 3] < 0.95)
    assert partial.sum() > 50
    assert rmse(vel.rgba, ref.rgba) < rmse(sharp.rgba, ref.rgba)
    assert abs(vel.rgba[..., 3].sum() - ref.rgba[..., 3].sum()) < 0.1 * ref.rgba[..., 3].sum()


@pytest.mark.parametrize("samples", [16, 64, 256])
def test_more_gather_samples_smooth_the_blur_without_adding_to_it(scene_path, samples):
    """The quad's smear past its sharp silhouette (alpha outside it) and its total alpha are those
    of the default 8 samples at any sample count (unscaled sample weights outgrew the centre's:
    the smear went 45 -> 52 -> 66 -> 76 px of alpha at 8, 16, 64, 256 samples)."""
    path = emissive_quad_stage(scene_path(), translate_samples={0.5: (-1.5, 0, 0), 1.5: (1.5, 0, 0)})
    outside = wb.render(path, frame=1, resolution=RES, samples=1, aovs=()).rgba[..., 3] == 0
    base = wb.render(path, frame=1, resolution=RES, method="velocity", aovs=()).rgba[..., 3]
    more = wb.render(path, frame=1, resolution=RES, method="velocity", samples=samples, aovs=()).rgba[..., 3]
    assert base[outside].sum() > 20
    assert more[outside].sum() == pytest.approx(base[outside].sum(), rel=0.03)
    assert more.sum() == pytest.approx(base.sum(), rel=0.01)


@pytest.mark.parametrize("who", ["object", "camera"])
def test_a_point_that_passes_behind_the_eye_blurs_over_the_half_it_is_seen(scene_path, who):
    """A small quad 6 units in front of the eye at shutter open and behind it at close (it moves,
    or the camera moves past it): it has no screen displacement (its motion AOV is 0, as SPEC's
    open-to-close displacement has no value there, and as the other methods write it), but the
    velocity blur takes twice its motion over the half it is seen in, so it blurs instead of
    staying sharp (before: unblurred where the quad moved; mirrored through the eye where the
    camera did)."""
    if who == "object":
        path = emissive_quad_stage(scene_path(), half=0.3,
                                   translate_samples={0.5: (-1.0, 0.3, 4.0), 1.5: (1.0, 0.3, 12.0)})
    else:
        path = emissive_quad_stage(scene_path(), half=0.3, translate=(0.6, 0.2, 4.0),
                                   camera={"translate_samples": {0.5: (0, 0, 10), 1.5: (0, 0, 2)}})
    ref = wb.render(path, frame=1, resolution=RES, samples=1024, aovs=())
    sharp = wb.render(path, frame=1, resolution=RES, samples=1, aovs=())
    vel = wb.render(path, frame=1, resolution=RES, method="velocity", aovs=("Z", "motion"))
    seen = np.isfinite(vel.aovs["Z"])
    assert seen.sum() > 20
    assert not vel.aovs["motion"][seen].any()
    assert vel.stats["velocity_max_px"] > 20
    assert rmse(vel.rgba, ref.rgba) < 0.92 * rmse(sharp.rgba, ref.rgba)


def test_extrusion_and_facing_options_run(scene_path):
    path = lit_stage(scene_path())
    a = wb.render(path, frame=1, resolution=RES, method="velocity", velocity_extrude=True, back_blur=0.5)
    assert np.isfinite(a.rgba).all()


@pytest.mark.parametrize("name", ["diagonal", "spin_edge_on", "occluder_pass", "dolly"])
def test_acceptance_beats_the_sharp_image(name):
    ref = read_exr(os.path.join(ACCEPTANCE, "refs", f"{name}.exr"))["RGBA"]
    scene = os.path.join(ACCEPTANCE, "scenes", f"{name}.usda")
    vel = wb.render(scene, frame=1, resolution=(128, 96), method="velocity", aovs=())
    sharp = wb.render(scene, frame=1, resolution=(128, 96), samples=1, aovs=())
    assert rmse(vel.rgba, ref) < rmse(sharp.rgba, ref)


def test_one_visibility_pass_gives_the_sharp_image_depth_and_motion(scene_path):
    """The velocity method shades, and writes Z and object motion, from one visibility pass: with
    motion under half a pixel (no gather) its image is the sharp image at the shutter centre, and
    its Z and motion AOVs are those of the separate depth/motion pass the other methods use."""
    path = lit_stage(scene_path(), shutter=(-0.002, 0.002))
    vel = wb.render(path, frame=1, resolution=RES, method="velocity", shadows="off")
    assert vel.stats["gather"] is False and vel.stats["velocity_max_px"] > 0
    centre = wb.render(path, frame=1, resolution=RES, samples=1, shutter=(0.0, 0.0), shadows="off", aovs=())
    acc = wb.render(path, frame=1, resolution=RES, samples=1, shadows="off")
    np.testing.assert_array_equal(vel.rgba, centre.rgba)
    np.testing.assert_array_equal(vel.aovs["Z"], acc.aovs["Z"])
    np.testing.assert_allclose(vel.aovs["motion"], acc.aovs["motion"], atol=1e-5)


def test_presence_passes_render_only_the_tiles_that_hold_translucent_surfaces(scene_path, monkeypatch):
    """Fractional opacity: the velocity method's extra presence passes re-render only the screen
    tiles whose bins hold a translucent triangle; the image equals re-rendering every pixel."""
    from scenes import translucent_layers_stage
    import warp_blur.methods.velocity as velocity
    path = translucent_layers_stage(scene_path())
    kw = dict(frame=1, method="velocity", resolution=(96, 72), aovs=(), shadow_map_size=256)
    tiles = wb.render(path, **kw)
    assert tiles.stats["presence_passes"] == velocity.PRESENCE_PASSES
    assert 0.05 < tiles.stats["presence_pixels"] < 0.9
    monkeypatch.setattr(velocity, "PRESENCE_TILES", False)
    every = wb.render(path, **kw)
    assert every.stats["presence_pixels"] == 1.0
    np.testing.assert_array_equal(tiles.rgba, every.rgba)


@pytest.mark.parametrize("extrude", [False, True])
def test_probed_instants_are_not_read_again(scene_path, monkeypatch, extrude):
    """The open and centre instants that the static-frame probes read are reused, never read
    twice; extrusion moves the centre's vertices in a copy, not in the probes' snapshot."""
    from warp_blur.usd.scene import Scene
    times = []
    snapshot = Scene.snapshot

    def counted(self, time, with_normals=True):
        times.append(time)
        return snapshot(self, time, with_normals)
    monkeypatch.setattr(Scene, "snapshot", counted)
    path = emissive_quad_stage(scene_path(), translate_samples={0.5: (-1, 0, 0), 1.5: (1, 0, 0)}, dome=None)
    r = wb.render(path, frame=1, resolution=RES, method="velocity", velocity_extrude=extrude)
    assert r.stats["gather"] is True
    assert sorted(times) == [0.5, 1.0, 1.5]   # probes at the centre and open, then close
