"""UsdGeom.Points as camera-facing discs (issue 19): a disc of known radius moving at a known
velocity covers, over the shutter, its own area in total, and along the row through its path
the time its centre spends within a radius of each pixel (the closed form of a moving disc)."""

import numpy as np
import pytest
from pxr import Gf, UsdGeom, Vt

import warp_blur as wb

RADIUS = 0.5          # world units (width 1)
SPEED = 2.0           # world units per frame, along +x
PIXEL = 10.0 / 128    # world units per pixel on the plane z = 0 (camera 10 away, window 1 wide at 1)


def _points_stage(path: str, velocity: bool = True) -> str:
    from authoring import add_camera, add_material, bind, new_stage
    stage = new_stage(path)
    add_camera(stage, shutter=(-0.5, 0.5))
    mat = add_material(stage, "/World/Looks/Emit", emissive=(1.0, 1.0, 1.0))
    pts = UsdGeom.Points.Define(stage, "/World/Sparks")
    if velocity:   # USD applies velocities to time-sampled positions: one sample, units per second
        pts.CreatePointsAttr().Set(Vt.Vec3fArray([Gf.Vec3f(0, 0, 0)]), 1.0)
        pts.CreateVelocitiesAttr().Set(Vt.Vec3fArray([Gf.Vec3f(SPEED * 24.0, 0, 0)]), 1.0)
    else:
        pts.CreatePointsAttr().Set(Vt.Vec3fArray([Gf.Vec3f(-SPEED / 2, 0, 0)]), 0.5)
        pts.CreatePointsAttr().Set(Vt.Vec3fArray([Gf.Vec3f(SPEED / 2, 0, 0)]), 1.5)
    pts.CreateWidthsAttr(Vt.FloatArray([2 * RADIUS]))
    bind(pts.GetPrim(), mat)
    stage.GetRootLayer().Save()
    return path


def _moving_disc_row(xs: np.ndarray) -> np.ndarray:
    """Covered fraction of the shutter at the row through the path: the centre (from -S/2 to S/2)
    within RADIUS of x."""
    lo, hi = np.maximum(xs - RADIUS, -SPEED / 2), np.minimum(xs + RADIUS, SPEED / 2)
    return np.clip(hi - lo, 0.0, None) / SPEED


@pytest.mark.parametrize("method,velocity", [("analytic", True), ("accumulation", True), ("stochastic", False)])
def test_a_moving_disc_covers_its_area_and_its_closed_form_streak(scene_path, method, velocity):
    path = _points_stage(scene_path(), velocity)
    kw = {"samples": 256} if method != "analytic" else {"time_bits": 0}
    result = wb.render(path, frame=1, method=method, resolution=(128, 96), shadows="off", **kw)
    alpha = result.rgba[..., 3].astype(np.float64)
    # over the shutter the disc covers its own area (the equal-area octagon keeps pi r^2)
    assert alpha.sum() * PIXEL ** 2 == pytest.approx(np.pi * RADIUS ** 2, rel=0.03)
    xs = (np.arange(128) + 0.5 - 64) * PIXEL
    row = 0.5 * (alpha[47] + alpha[48])           # the path runs between rows 47 and 48
    expected = _moving_disc_row(xs)
    assert np.abs(row - expected).max() < 0.06    # an octagon is 5% wider than the circle along x
    assert row[np.abs(xs) < 0.3].min() > 0.45     # the streak's middle: covered half the shutter
    assert alpha[:, np.abs(xs) > SPEED / 2 + RADIUS * 1.1].max() == 0.0


def test_points_face_the_camera_and_take_their_widths(scene_path):
    from authoring import add_camera, new_stage
    from warp_blur.usd.points import DISC_RADIUS_SCALE
    from warp_blur.usd.scene import Scene
    from warp_blur.usd.stage import Shutter, choose_camera, open_stage
    path = scene_path()
    stage = new_stage(path)
    add_camera(stage, rotate_axis="Y", rotate_samples={0: 30.0, 2: 30.0})
    pts = UsdGeom.Points.Define(stage, "/World/P")
    pts.CreatePointsAttr(Vt.Vec3fArray([Gf.Vec3f(0, 0, 0), Gf.Vec3f(1, 0, 0)]))
    pts.CreateWidthsAttr(Vt.FloatArray([0.2, 0.4]))
    stage.GetRootLayer().Save()
    st = open_stage(path)
    scene = Scene(st, choose_camera(st, None), 1.0, Shutter(0.5, 1.5))
    snap = scene.snapshot(1.0)
    per = len(snap.positions) // 2
    for i, width in enumerate((0.2, 0.4)):
        disc = snap.positions[i * per:(i + 1) * per]
        assert np.ptp(disc[:, 2]) < 1e-9                      # in a plane of constant camera depth
        extent = np.linalg.norm(disc[1:] - disc[0], axis=1)
        assert extent == pytest.approx(np.full(per - 1, width / 2 * DISC_RADIUS_SCALE), rel=1e-6)
