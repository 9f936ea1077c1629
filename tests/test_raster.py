"""The sharp rasterizer: emissive exactness, static invariance, watertight edges, near-plane clipping."""

import numpy as np
import pytest
from conftest import bin_in_entry_order
from scenes import emissive_quad_stage, lit_stage, skimming_stage, tilted_layers_stage

import warp_blur as wb
from warp_blur.output.metrics import max_abs


def test_emissive_quad_over_dome_is_exact(scene_path):
    path = emissive_quad_stage(scene_path(), with_light=True)
    r = wb.render(path, frame=1, resolution=(64, 48), samples=1)
    centre = r.rgba[24, 32]
    np.testing.assert_array_equal(centre, np.float32([0.9, 0.4, 0.2, 1.0]))
    np.testing.assert_array_equal(r.rgba[0, 0], np.float32([0.1, 0.12, 0.2, 0.0]))
    assert r.aovs["Z"][24, 32] == pytest.approx(10.0, abs=1e-5)
    assert np.isinf(r.aovs["Z"][0, 0])


def test_static_scene_identical_at_two_instants(scene_path):
    path = lit_stage(scene_path())
    # shadows off: the moving triangle's shadow would (rightly) move over the static quad
    a = wb.render(path, frame=1, resolution=(64, 48), samples=1, shutter=(-0.4, -0.4), shadows="off")
    b = wb.render(path, frame=1, resolution=(64, 48), samples=1, shutter=(0.3, 0.3), shadows="off")
    # the back quad is static, the triangle moves: where both instants see the quad, pixels are identical
    same = (np.abs(a.aovs["Z"] - 12.0) < 1e-3) & (np.abs(b.aovs["Z"] - 12.0) < 1e-3)
    assert same.sum() > 300
    np.testing.assert_array_equal(a.rgba[same], b.rgba[same])


def test_fully_static_scene_same_image_whatever_the_instant(scene_path):
    path = emissive_quad_stage(scene_path(), with_light=True)
    a = wb.render(path, frame=1, resolution=(64, 48), samples=1, shutter=(-0.4, -0.4))
    b = wb.render(path, frame=1, resolution=(64, 48), samples=1, shutter=(0.3, 0.3))
    np.testing.assert_array_equal(a.rgba, b.rgba)


def test_shared_edges_are_watertight_through_pixel_centres(scene_path):
    """An ortho grid whose edges (diagonals included) pass exactly through pixel centres: no holes."""
    from authoring import add_camera, add_material, add_mesh, grid, new_stage
    path = scene_path()
    stage = new_stage(path)
    # 32x32 image over a 32-unit window: pixel centres at half-integers
    add_camera(stage, projection="orthographic", haperture=320.0, vaperture=320.0)
    mat = add_material(stage, "/World/Looks/E", emissive=(1, 1, 1))
    pts, counts, idx = grid(16, 16, 16.0, 16.0)
    pts = [(x + 0.5, y + 0.5, 0.0) for x, y, _ in pts]
    tri_idx = []
    for f in range(len(counts)):
        a, b, c, d = idx[4 * f: 4 * f + 4]
        tri_idx += [a, b, c, a, c, d] if f % 2 else [a, b, d, b, c, d]
    add_mesh(stage, "/World/Grid", pts, [3] * (2 * len(counts)), tri_idx, material=mat)
    stage.GetRootLayer().Save()
    r = wb.render(path, frame=1, resolution=(32, 32), samples=1)
    inside = r.rgba[8:24, 8:24, 3]     # pixel centres strictly inside the grid
    assert inside.min() == 1.0


def test_perspective_fan_has_no_holes(scene_path):
    from authoring import add_camera, add_material, add_mesh, new_stage
    path = scene_path()
    stage = new_stage(path)
    add_camera(stage)
    mat = add_material(stage, "/World/Looks/E", emissive=(1, 1, 1))
    n = 97
    ang = np.linspace(0, 2 * np.pi, n, endpoint=False) + 0.123
    pts = [(0.01, -0.02, 0.0)] + [(3 * np.cos(a), 3 * np.sin(a), 0.3 * np.sin(5 * a)) for a in ang]
    idx = []
    for k in range(n):
        idx += [0, 1 + k, 1 + (k + 1) % n]
    add_mesh(stage, "/World/Fan", pts, [3] * n, idx, material=mat)
    stage.GetRootLayer().Save()
    r = wb.render(path, frame=1, resolution=(128, 96), samples=1)
    ys, xs = np.mgrid[0:96, 0:128]
    # pixels whose centre is well inside the fan's inscribed circle (radius ~2.9 units at depth ~10)
    wx = ((xs + 0.5) / 128 * 2 - 1) * 0.5 * 10
    wy = (1 - (ys + 0.5) / 96 * 2) * 0.375 * 10
    inner = wx ** 2 + wy ** 2 < 2.5 ** 2
    assert r.rgba[..., 3][inner].min() == 1.0


def test_near_plane_crossing_triangle_renders_its_visible_part(scene_path):
    """A triangle with one vertex behind the camera: compare coverage with a float64 ray cast."""
    from authoring import add_camera, add_material, add_mesh, new_stage
    path = scene_path()
    stage = new_stage(path)
    add_camera(stage, translate=(0, 0, 0), clipping=(0.5, 100))
    mat = add_material(stage, "/World/Looks/E", emissive=(1, 1, 1))
    tri = np.array([(-2.0, -1.5, -6.0), (2.5, -1.0, -4.0), (0.3, 0.8, 3.0)])  # last vertex behind the eye
    add_mesh(stage, "/World/T", tri.tolist(), [3], [0, 1, 2], material=mat)
    stage.GetRootLayer().Save()
    w, h = 128, 96
    r = wb.render(path, frame=1, resolution=(w, h), samples=1)
    ys, xs = np.mgrid[0:h, 0:w]
    d = np.stack([((xs + 0.5) / w * 2 - 1) * 0.5, (1 - (ys + 0.5) / h * 2) * 0.375, -np.ones((h, w))], -1)
    a, b, c = tri
    n = np.cross(b - a, c - a)
    t = (a @ n) / (d @ n)
    p = d * t[..., None]
    depth = -p[..., 2]

    def edge(p0, p1):
        return np.cross(p1 - p0, p - p0) @ n
    e = np.stack([edge(a, b), edge(b, c), edge(c, a)], -1) / np.linalg.norm(n)
    inside = (e > 0).all(-1) & (depth >= 0.5) & (depth <= 100)
    margin = (np.abs(e).min(-1) > 1e-4) & (np.abs(depth - 0.5) > 1e-4)
    cov = r.rgba[..., 3] > 0.5
    assert inside.sum() > 500
    np.testing.assert_array_equal(cov[margin], inside[margin])
    # nothing behind the eye: the part of the triangle's plane behind the camera never shows
    assert not cov[(t < 0) & margin].any()


def test_nearest_first_lists_stop_early_and_change_no_pixel(scene_path, monkeypatch):
    """Sharp passes walk tile lists nearest first and stop at the first entry wholly beyond the
    hit they hold (raster.list_beyond); ties in depth still go to the lower entry index. The
    images and AOVs equal those of lists in entry order walked to the end (bins without
    entry_near), for accumulation (sharp instants) and the AOV pass, on a stack of steeply
    tilted, interpenetrating layers with a coplanar pair of quads in front."""
    path = tilted_layers_stage(scene_path())
    kw = dict(frame=1, resolution=(96, 72), method="accumulation", samples=4, shadows="off")
    nearest_first = wb.render(path, **kw)
    bin_in_entry_order(monkeypatch)
    walked = wb.render(path, **kw)
    np.testing.assert_array_equal(nearest_first.rgba, walked.rgba)
    for name in ("Z", "motion"):
        np.testing.assert_array_equal(nearest_first.aovs[name], walked.aovs[name])
    # the coplanar pair shows its first quad (the lower index), in both
    centre = nearest_first.rgba[nearest_first.aovs["Z"] == nearest_first.aovs["Z"].min()]
    assert len(centre) and (centre[:, 0] > 0.5).all() and (centre[:, 1] < 0.1).all()


def test_analytic_nearest_first_lists_change_no_pixel(scene_path, monkeypatch):
    """Analytic's walks over lists running nearest first (classify's search for the first moving
    entry that reaches a sample stops at the first one wholly beyond the static surface; the
    static walk and the fill's culling stop early too) give the image of lists in entry order
    walked to the end, on tilted, interpenetrating moving layers behind a still coplanar pair, and
    on quads sliding just in front of (and behind) a still wall: the same samples listed (interval
    count aside, which culling changes) and the same colours to float rounding (the resolve sums
    the visible intervals in another order)."""
    kw = dict(frame=1, resolution=(96, 72), method="analytic", aovs=(), shadows="off")
    paths = (tilted_layers_stage(scene_path()), skimming_stage(scene_path()))
    nearest_first = [wb.render(path, **kw) for path in paths]
    bin_in_entry_order(monkeypatch)
    for path, first in zip(paths, nearest_first):
        walked = wb.render(path, **kw)
        assert first.stats["pixels_with_motion"] == walked.stats["pixels_with_motion"]
        assert 0.05 < first.stats["pixels_with_motion"] < 0.95
        assert max_abs(first.rgba, walked.rgba) <= 1e-6
    # the quads skimming the wall show over it; the one behind it (rows 23-26) never does
    skim = nearest_first[1].rgba
    assert (skim[..., 0] > 0.5).sum() > 50
    np.testing.assert_allclose(skim[23:27, 22:75, :3], 0.3, atol=1e-5)
