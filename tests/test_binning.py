"""Tile binning: slab culling (swept_bands) drops only (entry, tile) pairs and samples that no coverage could keep."""

import os

import numpy as np
import pytest

import warp_blur as wb
from warp_blur.core.camera import Projection
from warp_blur.raster.binning import TILE_SIZE, bin_entries, entry_corners


def band_misses_tiles(bands: np.ndarray, tx: np.ndarray, ty: np.ndarray, tile_size: int) -> np.ndarray:
    """The slab rule of raster/tile_lists.py (slabs_reach), in NumPy: the reference its lists are
    checked against. (P,) True where a slab (P, 4) of an entry (swept_bands) misses its tile (tx, ty)
    altogether: no sample of the tile passes the kernels' slab test (box_rejects), so the pair
    need not be listed. The tile's range along the slab's normal is its centre's ± the half
    extent; a 1e-3 px slack keeps the answer on the kernels' side of float32 rounding."""
    half = 0.5 * tile_size
    nx, ny = bands[:, 0].astype(np.float64), bands[:, 1].astype(np.float64)
    centre = nx * (tx * tile_size + half) + ny * (ty * tile_size + half)
    reach = (np.abs(nx) + np.abs(ny)) * half + 1.0e-3
    return (centre + reach < bands[:, 2]) | (centre - reach > bands[:, 3])


def _kernel_band_keeps(bands: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The kernels' band test (box_rejects) in float32: (P, S) True where sample (x, y) passes."""
    b = bands.astype(np.float32)
    w = b[:, 0:1] * x.astype(np.float32) + b[:, 1:2] * y.astype(np.float32)
    return (w >= b[:, 2:3]) & (w <= b[:, 3:4])


def test_entry_corners_are_each_entrys_vertices_at_its_two_knots():
    rng = np.random.default_rng(3)
    positions = rng.normal(size=(5, 40, 3))
    tri_vertices = rng.integers(0, 40, (30, 3))
    entry_tri = rng.integers(0, 30, 100)
    k0 = rng.integers(0, 4, 100)
    k1 = k0 + rng.integers(0, 2, 100)
    pts = entry_corners(positions, tri_vertices, entry_tri, k0, k1)
    assert pts.shape == (6, 100, 3)
    for e in range(100):
        for j in range(3):
            v = tri_vertices[entry_tri[e], j]
            assert np.array_equal(pts[j, e], positions[k0[e], v])
            assert np.array_equal(pts[3 + j, e], positions[k1[e], v])


def test_band_culling_never_drops_a_tile_with_a_sample_the_kernel_keeps():
    rng = np.random.default_rng(7)
    pairs = 4000
    angle = rng.uniform(0.0, 2.0 * np.pi, pairs)
    lo = rng.uniform(-400.0, 400.0, pairs)
    bands = np.stack([np.cos(angle), np.sin(angle), lo, lo + rng.uniform(0.5, 40.0, pairs)], axis=1)
    tx, ty = rng.integers(0, 40, pairs), rng.integers(0, 30, pairs)
    # samples anywhere in the tile, its corners and edges included (pixel centres, jitter, edges)
    u = np.concatenate([rng.uniform(0.0, 1.0, 200), [0.0, 1.0, 0.0, 1.0, 0.5]])
    v = np.concatenate([rng.uniform(0.0, 1.0, 200), [0.0, 0.0, 1.0, 1.0, 0.5]])
    x = (tx[:, None] + u[None, :]) * TILE_SIZE
    y = (ty[:, None] + v[None, :]) * TILE_SIZE
    keeps = _kernel_band_keeps(bands, x, y).any(axis=1)
    misses = band_misses_tiles(bands, tx, ty, TILE_SIZE)
    assert not (misses & keeps).any()
    # and it does drop something: the test can tell a useless cull from a working one
    assert misses.sum() > pairs // 4


def test_a_diagonal_streak_lists_only_the_tiles_along_it():
    proj = Projection(False, (-1.0, -0.75, 1.0, 0.75), 0.1, 100.0, 640, 480)
    box = np.array([[0.0, 0.0, 640.0, 480.0]])
    n = np.array([-480.0, 640.0]) / 800.0        # normal of the diagonal (0, 0) -> (640, 480)
    band = np.array([[n[0], n[1], -4.0, 4.0]])
    keep = np.array([True])
    full = bin_entries(proj, box, keep, TILE_SIZE)
    culled = bin_entries(proj, box, keep, TILE_SIZE, bands=band)
    assert full.num_pairs == 40 * 30
    assert 40 <= culled.num_pairs < 200
    # every pixel centre within the band lies in a listed tile
    ys, xs = np.mgrid[0:480, 0:640] + 0.5
    inside = np.abs(n[0] * xs + n[1] * ys) <= 4.0
    tiles = set(np.unique((ys[inside] // TILE_SIZE).astype(int) * 40 + (xs[inside] // TILE_SIZE).astype(int)))
    listed = {t for t in range(40 * 30) if culled.tile_offsets[t + 1] > culled.tile_offsets[t]}
    assert tiles <= listed


def test_a_moving_triangle_crossing_the_near_plane_is_boxed_by_its_part_in_front():
    """entry_pixel_bounds: a moving entry whose vertices straddle the near plane gets the box of
    its swept hull's part in front of the plane, which holds every point of the triangle, at any
    time of its span, that is in front of the plane (so no sample the kernels keep is lost) and
    is not the whole screen for a ground running under the camera."""
    from warp_blur.raster.binning import entry_pixel_bounds
    proj = Projection(False, (-0.5, -0.375, 0.5, 0.375), 0.5, 500.0, 640, 480)
    rng = np.random.default_rng(11)
    n = 300
    # triangles around the eye's depth, moving by up to a few units: most cross the near plane
    p0 = rng.uniform([-3.0, -3.0, -4.0], [3.0, 3.0, 1.0], (n, 3, 3))
    p1 = p0 + rng.uniform(-2.0, 2.0, (n, 1, 3)) + rng.normal(0.0, 0.3, (n, 3, 3))
    positions = np.concatenate([p0.reshape(1, -1, 3), p1.reshape(1, -1, 3)])     # knots 0, 1
    tri_vertices = np.arange(3 * n).reshape(n, 3)
    entry = np.arange(n)
    boxes, keep = entry_pixel_bounds(proj, positions, tri_vertices, entry, np.zeros(n, int), np.ones(n, int), 0.05)
    # points of each triangle at many times and barycentrics, in front of the near plane
    s = rng.uniform(0.0, 1.0, (n, 400, 1))
    w = rng.dirichlet((1.0, 1.0, 1.0), (n, 400))
    a = p0[:, None] + s[..., None] * (p1 - p0)[:, None]                         # (n, 400, 3, 3)
    pts = (w[..., None] * a).sum(axis=2)                                         # (n, 400, 3)
    r = proj.project(pts)
    # in front of the near plane and on screen: a sample there must find the entry in its tile
    seen = (-pts[..., 2] >= proj.near) & (r[..., 0] >= 0) & (r[..., 0] <= 640) & (r[..., 1] >= 0) & (r[..., 1] <= 480)
    crossing = ((-p0[..., 2] < proj.near) | (-p1[..., 2] < proj.near)).any(axis=1)
    assert crossing.sum() > n // 3 and (seen.any(axis=1) & crossing).sum() > n // 10
    for i in np.nonzero(seen.any(axis=1))[0]:
        assert keep[i]
        q = r[i][seen[i]]
        assert (q[:, 0] >= boxes[i, 0]).all() and (q[:, 0] <= boxes[i, 2]).all()
        assert (q[:, 1] >= boxes[i, 1]).all() and (q[:, 1] <= boxes[i, 3]).all()
    # a ground quad running under a camera that trucks forward: its box is the lower screen only
    ground = np.array([[[-5.0, -1.0, 2.0], [5.0, -1.0, 2.0], [0.0, -1.0, -30.0]]])
    moved = ground + np.array([0.0, 0.0, 1.5])
    box, _ = entry_pixel_bounds(proj, np.concatenate([ground, moved]), np.array([[0, 1, 2]]), np.array([0]),
                                np.array([0]), np.array([1]), 0.05)
    assert box[0, 1] > proj.height / 2 - 1    # nothing above the horizon (the screen's middle row)


def test_swept_slabs_hold_every_point_a_moving_triangle_covers_and_a_still_one_is_its_own_slabs():
    """swept_bands: every point of a moving triangle, at any time of its span, lies in each of its
    slabs (its six projected vertices' hull holds it while it is in front of the eye); entries
    that cross the near plane get no reject; a still triangle's slabs are the triangle (points off
    it by more than the margin are rejected), as a translating one's are the hexagon it sweeps."""
    from warp_blur.raster.binning import BAND_SLABS, swept_bands
    proj = Projection(False, (-0.5, -0.375, 0.5, 0.375), 0.5, 500.0, 640, 480)
    rng = np.random.default_rng(5)
    n = 300
    p0 = rng.uniform([-3.0, -3.0, -12.0], [3.0, 3.0, -1.0], (n, 3, 3))
    p1 = p0 + rng.uniform(-2.0, 2.0, (n, 1, 3)) + rng.normal(0.0, 0.5, (n, 3, 3))
    p1[: n // 10] = p0[: n // 10]                                               # some hold still
    positions = np.concatenate([p0.reshape(1, -1, 3), p1.reshape(1, -1, 3)])
    tri_vertices = np.arange(3 * n).reshape(n, 3)
    slabs = swept_bands(proj, positions, tri_vertices, np.arange(n), np.zeros(n, int), np.ones(n, int), 0.05)
    assert slabs.shape == (n, BAND_SLABS, 4)
    sharp = swept_bands(proj, positions, tri_vertices, np.arange(n), np.zeros(n, int), np.zeros(n, int), 0.05)
    assert sharp.shape == (n, 1, 4) and (sharp == np.array([0, 0, -1, 1], np.float32)).all()   # nothing moves
    s = rng.uniform(0.0, 1.0, (n, 400, 1))
    w = rng.dirichlet((1.0, 1.0, 1.0), (n, 400))
    pts = (w[..., None] * (p0[:, None] + s[..., None] * (p1 - p0)[:, None])).sum(axis=2)
    r = proj.project(pts)                                                        # (n, 400, 2)
    crossing = ((-p0[..., 2] < proj.near) | (-p1[..., 2] < proj.near)).any(axis=1)
    assert 0 < crossing.sum() < n // 2
    along = r[:, :, None, 0] * slabs[:, None, :, 0] + r[:, :, None, 1] * slabs[:, None, :, 1]   # (n, 400, S)
    inside = (along >= slabs[:, None, :, 2]) & (along <= slabs[:, None, :, 3])
    front = ~crossing
    assert inside[front].all()
    assert (slabs[crossing, :, :2] == 0).all()                                  # no reject where it crosses
    # a still triangle: pixels of its box off the triangle by more than the margin fail a slab
    still = np.nonzero(front[: n // 10])[0]
    assert len(still) > 10
    for i in still[:10]:
        tri = proj.project(p0[i])                                                # (3, 2)
        lo, hi = tri.min(axis=0), tri.max(axis=0)
        q = lo + rng.uniform(0.0, 1.0, (2000, 2)) * (hi - lo)
        a, b, c = tri
        def cross(u, v):
            return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]
        d = [cross(v1 - v0, q - v0) / np.hypot(*(v1 - v0)) for v0, v1 in ((a, b), (b, c), (c, a))]
        sign = np.sign(cross(b - a, c - a))
        outside = (np.stack(d) * sign < -0.06).any(axis=0)                      # off an edge by > margin
        wq = q[:, None, 0] * slabs[i, None, :, 0] + q[:, None, 1] * slabs[i, None, :, 1]
        kept = ((wq >= slabs[i, None, :, 2]) & (wq <= slabs[i, None, :, 3])).all(axis=1)
        assert outside.sum() > 200 and not (kept & outside).any()


@pytest.mark.parametrize("method", ["analytic", "stochastic", "accumulation"])
@pytest.mark.parametrize("scene", ["deep_overlap", "rotation"])
def test_slab_rejects_change_no_image(monkeypatch, method, scene):
    """The slabs only skip work: images with them equal images with no slab reject at all."""
    import warp_blur.methods.frame as frame
    from conftest import SCENES
    path = os.path.join(SCENES, f"{scene}.usda")
    kw = dict(frame=2, method=method, resolution=(96, 72), samples=8 if method != "analytic" else 4)
    with_slabs = wb.render(path, **kw).rgba
    real = frame.entry_bounds

    def no_slabs(*a, **k):
        box, keep, bands, near = real(*a, **k)
        return box, keep, bands[:, :0], near
    monkeypatch.setattr(frame, "entry_bounds", no_slabs)   # no slabs at all
    assert np.array_equal(with_slabs, wb.render(path, **kw).rgba)


def _lists_by_brute_force(proj, boxes, keep, tile_size, near_depth, bands):
    """Every tile's entries, one pair at a time: the box reaches the tile and no slab misses it
    (band_misses_tiles), in ascending (near_depth, entry index)."""
    tiles_x = (proj.width + tile_size - 1) // tile_size
    tiles_y = (proj.height + tile_size - 1) // tile_size
    lists = [[] for _ in range(tiles_x * tiles_y)]
    entries = [e for e in range(len(boxes)) if keep[e]]
    entries.sort(key=lambda e: (near_depth[e], e))
    for e in entries:
        x0, y0, x1, y1 = (int(np.clip(np.floor(v / tile_size), 0, n - 1))
                          for v, n in zip(boxes[e], (tiles_x, tiles_y, tiles_x, tiles_y)))
        for ty in range(y0, y1 + 1):
            for tx in range(x0, x1 + 1):
                slabs = bands[e]
                misses = band_misses_tiles(slabs, np.full(len(slabs), tx), np.full(len(slabs), ty), tile_size)
                if not misses.any():
                    lists[ty * tiles_x + tx].append(e)
    return lists


def test_tile_lists_hold_each_tiles_entries_in_key_order_as_pair_by_pair_binning_does():
    """bin_entries (tile_lists.py's kernels) against binning every (entry, tile) pair on its own:
    boxes partly off screen, slabs that pass everything (zero normal) or cut corners, and order
    keys with ties (broken by entry index)."""
    proj = Projection(False, (-1.0, -0.75, 1.0, 0.75), 0.1, 100.0, 200, 150)
    rng = np.random.default_rng(5)
    n = 300
    lo = rng.uniform(-40.0, 210.0, (n, 2))
    boxes = np.concatenate([lo, lo + rng.uniform(0.5, 80.0, (n, 2))], axis=1)
    keep = rng.uniform(size=n) < 0.9
    near_depth = rng.integers(0, 20, n).astype(np.float64)   # many ties
    angle = rng.uniform(0.0, 2.0 * np.pi, (n, 3))
    centre = 0.5 * (boxes[:, :2] + boxes[:, 2:])
    # slabs about each box's centre, some narrower than the box (they cut tiles), some wider
    along = np.cos(angle) * centre[:, :1] + np.sin(angle) * centre[:, 1:]
    half = rng.uniform(2.0, 60.0, (n, 3))
    bands = np.stack([np.cos(angle), np.sin(angle), along - half, along + half], axis=2)
    bands[::4, 1] = (0.0, 0.0, -1.0, 1.0)                   # some pass-all slabs
    bands = bands.astype(np.float32)
    for tile_size in (16, 8):
        bins = bin_entries(proj, boxes, keep, tile_size, near_depth, bands)
        expected = _lists_by_brute_force(proj, boxes, keep, tile_size, near_depth, bands)
        got = [list(bins.tile_entries[bins.tile_offsets[t]:bins.tile_offsets[t + 1]]) for t in range(len(expected))]
        assert got == expected
        assert bins.num_pairs == sum(len(x) for x in expected) > n   # slabs and boxes both at work
    # without an order key each tile lists its entries by index; without slabs, by box alone
    plain = bin_entries(proj, boxes, keep, 16)
    for t in range(plain.tiles_x * plain.tiles_y):
        listed = plain.tile_entries[plain.tile_offsets[t]:plain.tile_offsets[t + 1]]
        assert np.all(np.diff(listed) > 0)
    assert plain.num_pairs > bin_entries(proj, boxes, keep, 16, bands=bands).num_pairs
