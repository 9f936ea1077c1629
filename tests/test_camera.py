"""Projection agrees with USD's own Gf.Camera / Gf.Frustum; conform and pixel centres per SPEC."""

import numpy as np
import pytest
from pxr import Gf, Usd, UsdGeom

from warp_blur.core.camera import conform_window
from warp_blur.usd.stage import projection_at


def _gf_raster(frustum: Gf.Frustum, p_cam: np.ndarray, w: int, h: int) -> np.ndarray:
    m = np.array(frustum.ComputeProjectionMatrix(), np.float64)
    hom = np.concatenate([p_cam, np.ones((len(p_cam), 1))], axis=1) @ m
    ndc = hom[:, :2] / hom[:, 3:4]
    return np.stack([(ndc[:, 0] + 1) / 2 * w, (1 - ndc[:, 1]) / 2 * h], axis=1)


@pytest.mark.parametrize("projection", ["perspective", "orthographic"])
@pytest.mark.parametrize("offsets", [(0.0, 0.0), (2.0, -1.5)])
def test_projection_matches_gf_frustum(scene_path, projection, offsets):
    from authoring import add_camera, new_stage
    path = scene_path()
    stage = new_stage(path)
    cam = add_camera(stage, projection=projection, focal=35.0, haperture=36.0, vaperture=24.0,
                     hoffset=offsets[0], voffset=offsets[1])
    stage.GetRootLayer().Save()
    w, h = 150, 100  # aperture aspect 1.5: no conform
    proj = projection_at(cam, 1.0, (w, h))
    rng = np.random.default_rng(1)
    p = np.stack([rng.uniform(-3, 3, 50), rng.uniform(-2, 2, 50), rng.uniform(-30, -1, 50)], axis=1)
    frustum = cam.GetCamera(Usd.TimeCode(1.0)).frustum
    np.testing.assert_allclose(proj.project(p), _gf_raster(frustum, p, w, h), rtol=0, atol=1e-6)


def test_expand_aperture_grows_the_short_side():
    win = conform_window((-0.5, -0.375, 0.5, 0.375), 2.0)  # 4:3 window into a 2:1 image
    assert win == pytest.approx((-0.75, -0.375, 0.75, 0.375))
    win = conform_window((-0.5, -0.375, 0.5, 0.375), 1.0)
    assert win == pytest.approx((-0.5, -0.5, 0.5, 0.5))
    win = conform_window((-0.5, -0.375, 0.5, 0.375), 2.0, "cropAperture")
    assert win == pytest.approx((-0.5, -0.25, 0.5, 0.25))


def test_pixel_centre_of_image_centre_projects_to_axis(scene_path):
    from authoring import add_camera, new_stage
    path = scene_path()
    stage = new_stage(path)
    cam = add_camera(stage)
    proj = projection_at(cam, 0.0, (128, 96))
    # a point on the view axis lands exactly between the four centre pixels
    assert proj.project(np.array([[0.0, 0.0, -5.0]]))[0] == pytest.approx([64.0, 48.0])
    assert isinstance(cam, UsdGeom.Camera)
