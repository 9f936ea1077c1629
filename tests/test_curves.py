"""UsdGeom.BasisCurves as camera-facing ribbons (issue 19): curves sampled as USD's bases define
them, ribbons of their widths, blurred by their points' motion like meshes."""

import numpy as np
import pytest
from pxr import Gf, UsdGeom, Vt

import warp_blur as wb
from warp_blur.usd.curves import BASES, curve_layout, ribbon_triangles, sample_positions

PIXEL = 10.0 / 128    # world units per pixel on z = 0 (camera 10 away, window 1 wide at distance 1)
WIDTH = 3 * PIXEL     # three pixels: the edges fall between 4x4 sub-pixel samples, never on one


@pytest.mark.parametrize("basis,wrap,count", [("bezier", "nonperiodic", 7), ("catmullRom", "pinned", 5),
                                              ("bspline", "nonperiodic", 6), ("catmullRom", "periodic", 5)])
def test_curve_samples_follow_the_basis(basis, wrap, count):
    rng = np.random.default_rng(1)
    pts = rng.uniform(-1, 1, (count, 3))
    layout = curve_layout("cubic", basis, wrap, np.array([count]))
    s = sample_positions(layout, pts, np.array([count]), wrap)
    if basis == "bezier" or wrap == "pinned":     # these pass through their end points
        assert np.allclose(s[0], pts[0]) and np.allclose(s[-1], pts[-1])
    # the first segment's middle sample is the basis at t = 1/2 (SAMPLES_PER_SEGMENT is even: the
    # nearest sample parameters straddle it), checked against the matrix directly
    t = np.linspace(0, 1, 8)[3]
    first_four = {"pinned": np.r_[[2 * pts[0] - pts[1]], pts[:3]]}.get(wrap, pts[:4])
    expected = np.array([t ** 3, t ** 2, t, 1.0]) @ BASES[basis] @ first_four
    assert np.allclose(s[3], expected)
    assert ribbon_triangles(layout).shape == (2 * (len(s) - 1), 3)
    assert curve_layout("cubic", "bezier", "nonperiodic", np.array([6])) is None   # not 3n + 1


def _curve_stage(path: str, moving: bool) -> str:
    from authoring import add_camera, add_material, bind, new_stage
    stage = new_stage(path)
    add_camera(stage, shutter=(-0.5, 0.5))
    mat = add_material(stage, "/World/Looks/Emit", emissive=(1.0, 1.0, 1.0))
    curves = UsdGeom.BasisCurves.Define(stage, "/World/Wire")
    curves.CreateTypeAttr("linear")
    curves.CreateCurveVertexCountsAttr(Vt.IntArray([3]))
    line = [Gf.Vec3f(-2, 0, 0), Gf.Vec3f(0, 0, 0), Gf.Vec3f(2, 0, 0)]
    if moving:   # one unit down over the shutter
        curves.CreatePointsAttr().Set(Vt.Vec3fArray([p + Gf.Vec3f(0, 0.5, 0) for p in line]), 0.5)
        curves.CreatePointsAttr().Set(Vt.Vec3fArray([p - Gf.Vec3f(0, 0.5, 0) for p in line]), 1.5)
    else:
        curves.CreatePointsAttr(Vt.Vec3fArray(line))
    curves.CreateWidthsAttr(Vt.FloatArray([WIDTH]))
    bind(curves.GetPrim(), mat)
    stage.GetRootLayer().Save()
    return path


@pytest.mark.parametrize("method", ["analytic", "accumulation", "stochastic", "velocity"])
def test_a_ribbon_covers_its_area_still_and_moving(scene_path, method):
    kw = {"samples": 16, "spatial_samples": 4} if method != "analytic" else {"spatial_samples": 4}
    still = wb.render(_curve_stage(scene_path(), False), frame=1, method=method, resolution=(128, 96),
                      shadows="off", **kw).rgba[..., 3]
    assert still.sum() * PIXEL ** 2 == pytest.approx(4.0 * WIDTH, rel=0.01)    # length x width
    cols = (np.arange(128) + 0.5 - 64) * PIXEL
    assert still[:, np.abs(cols) > 2.1].max() == 0.0
    moving = wb.render(_curve_stage(scene_path(), True), frame=1, method=method, resolution=(128, 96),
                       shadows="off", **kw).rgba[..., 3]
    rows_covered = [(a[:, 60:68].max(axis=1) > 0.01).sum() for a in (still, moving)]
    assert rows_covered[1] >= rows_covered[0] + 8          # blurred over the unit (12.8 px) it moves
    if method != "velocity":   # exact methods keep the area; the velocity gather is an approximation
        assert moving.sum() * PIXEL ** 2 == pytest.approx(4.0 * WIDTH, rel=0.03)    # spread over the unit it moves: WIDTH / 1 of the shutter in the middle
        rows = moving[:, 60:68].mean(axis=1)
        assert rows[48 - 4:48 + 4].mean() == pytest.approx(WIDTH, abs=0.03) and rows.max() < WIDTH + 0.06
