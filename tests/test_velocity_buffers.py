"""The velocity method's buffer kernels against the NumPy forms they replaced (float64, one core),
kept here as the oracle: camera motion from depth, soft-edge velocity, tile and neighbour maxima."""

import numpy as np
import pytest
import warp as wp

from warp_blur.core.affine import invert_affine
from warp_blur.core.camera import Projection
from warp_blur.methods import velocity_buffers as vb

W, H = 61, 45   # odd sizes: the half-resolution and tile edges are partial


# ------------------------------------------------------------------ the NumPy forms (the oracle)
def camera_motion_numpy(proj: Projection, depth: np.ndarray, open_from_center: np.ndarray,
                        close_from_center: np.ndarray, half_seen: bool = False) -> np.ndarray:
    """(H, W, 2) the camera's screen motion of what each pixel sees: 0 where a point is behind
    the eye at open or close (perspective), or with half_seen twice its motion over the half of
    the shutter it is seen in (the pixel itself at the centre)."""
    h, w = depth.shape
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float64) + 0.5
    wx, wy = proj.pixel_window_coords(xs, ys)
    z = np.where(np.isfinite(depth), depth, 0.0).astype(np.float64)
    if proj.orthographic:
        p = np.stack([wx, wy, -z, np.ones_like(z)], -1)
    else:
        p = np.stack([wx * z, wy * z, -z, np.ones_like(z)], -1)
    far = ~np.isfinite(depth)
    if not proj.orthographic:
        p[far] = np.stack([wx[far], wy[far], -np.ones(far.sum()), np.zeros(far.sum())], -1)
    p_open = (p @ open_from_center)[..., :3]
    p_close = (p @ close_from_center)[..., :3]
    with np.errstate(divide="ignore", invalid="ignore"):
        motion = proj.project(p_close) - proj.project(p_open)
    behind = far & ((p_open[..., 2] >= 0) | (p_close[..., 2] >= 0))
    motion[~np.isfinite(motion).all(-1) | behind | (far & proj.orthographic)] = 0.0
    if not proj.orthographic:
        open_behind = ~far & (p_open[..., 2] >= 0)
        close_behind = ~far & (p_close[..., 2] >= 0)
        motion[open_behind | close_behind] = 0.0
        if half_seen:
            centre = np.stack([xs, ys], -1)
            with np.errstate(divide="ignore", invalid="ignore"):
                only_close = close_behind & ~open_behind
                motion[only_close] = 2 * (centre - proj.project(p_open))[only_close]
                only_open = open_behind & ~close_behind
                motion[only_open] = 2 * (proj.project(p_close) - centre)[only_open]
    return motion


def box_blur_numpy(a: np.ndarray, r: int, axis: int) -> np.ndarray:
    a = np.moveaxis(a, axis, 0)
    n = a.shape[0]
    c = np.concatenate([np.zeros((1,) + a.shape[1:]), np.cumsum(a, axis=0)])
    i = np.arange(n)
    out = (c[np.minimum(i + r + 1, n)] - c[np.maximum(i - r, 0)]) / (2 * r + 1)
    return np.moveaxis(out, 0, axis)


def soft_edge_numpy(v: np.ndarray, radius: float) -> np.ndarray:
    if radius <= 0:
        return v
    h, w, _ = v.shape
    h2, w2 = (h + 1) // 2, (w + 1) // 2
    pad = np.zeros((h2 * 2, w2 * 2, 2))
    pad[:h, :w] = v
    low = pad.reshape(h2, 2, w2, 2, 2).mean(axis=(1, 3))
    mask = (np.linalg.norm(low, axis=-1) > 1e-3).astype(np.float64)
    r = max(1, int(round(radius / 2)))

    def blur(a):
        return box_blur_numpy(box_blur_numpy(a, r, 0), r, 1)
    num = np.stack([blur(low[..., 0] * mask), blur(low[..., 1] * mask)], -1)
    den = blur(mask)[..., None]
    soft = np.where(den > 1e-6, num / np.maximum(den, 1e-6), 0.0)
    up = soft.repeat(2, axis=0).repeat(2, axis=1)[:h, :w]
    moving = np.linalg.norm(v, axis=-1, keepdims=True) > 1e-3
    return np.where(moving, v, up)


def neighbour_max_numpy(vhalf: np.ndarray, tile: int) -> tuple[np.ndarray, int]:
    h, w, _ = vhalf.shape
    ty, tx = (h + tile - 1) // tile, (w + tile - 1) // tile
    pad = np.zeros((ty * tile, tx * tile, 2))
    pad[:h, :w] = vhalf
    blocks = pad.reshape(ty, tile, tx, tile, 2).transpose(0, 2, 1, 3, 4).reshape(ty, tx, tile * tile, 2)
    idx = np.linalg.norm(blocks, axis=-1).argmax(axis=-1)
    tmax = np.take_along_axis(blocks, idx[..., None, None], axis=2)[:, :, 0]
    padded = np.zeros((ty + 2, tx + 2, 2))
    padded[1:-1, 1:-1] = tmax
    cands = np.stack([padded[1 + dy:1 + dy + ty, 1 + dx:1 + dx + tx] for dy in (-1, 0, 1) for dx in (-1, 0, 1)], 2)
    best = np.linalg.norm(cands, axis=-1).argmax(axis=-1)
    nmax = np.take_along_axis(cands, best[..., None, None], axis=2)[:, :, 0]
    return nmax.reshape(-1, 2), tx


# ------------------------------------------------------------------ inputs
def turn_and_shift(angle: float, axis: np.ndarray, shift: np.ndarray) -> np.ndarray:
    """A rigid 4×4 (row vectors) turning by angle about unit axis, then shifting."""
    a = axis / np.linalg.norm(axis)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    r = np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k
    m = np.eye(4)
    m[:3, :3] = r.T
    m[3, :3] = shift
    return m


def random_velocity(rng: np.random.Generator) -> np.ndarray:
    """(H, W, 2) pixels: moving blobs on a still background, and a few specks."""
    v = np.zeros((H, W, 2))
    v[10:25, 8:30] = rng.normal(0, 6, 2)
    v[30:44, 40:60] = rng.normal(0, 20, (14, 20, 2))
    v[rng.integers(0, H, 9), rng.integers(0, W, 9)] = rng.normal(0, 3, (9, 2))
    return v.astype(np.float32)


@pytest.mark.parametrize("half_seen", [False, True])
@pytest.mark.parametrize("ortho", [False, True])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_camera_motion_matches_numpy(ortho, seed, half_seen):
    rng = np.random.default_rng(seed)
    proj = Projection(orthographic=ortho, window=(-0.6, -0.45, 0.8, 0.5), near=0.1, far=1e4, width=W, height=H)
    depth = rng.uniform(0.5, 40, (H, W)).astype(np.float32)
    depth[rng.random((H, W)) < 0.2] = np.inf   # nothing hit: the dome's direction
    depth[:3, :3] = 0.05                       # near the eye: the open camera may put it behind
    cfw = [turn_and_shift(rng.normal(0, 0.3), rng.normal(size=3), rng.normal(0, 0.4, 3)) for _ in range(3)]
    to_open, to_close = invert_affine(cfw[1]) @ cfw[0], invert_affine(cfw[1]) @ cfw[2]
    want = camera_motion_numpy(proj, depth, to_open, to_close, half_seen)
    base = rng.normal(0, 2, (H * W, 2)).astype(np.float32)
    motion = wp.array(base, dtype=wp.vec2, device="cpu")
    vb.camera_motion(wp.array(depth.ravel(), dtype=float, device="cpu"), motion, proj, to_open, to_close, "cpu",
                     half_seen=half_seen)
    got = motion.numpy().reshape(H, W, 2) - base.reshape(H, W, 2)
    big = np.abs(want) > 1e4   # points just behind the eye project far off: compare those relatively
    assert np.abs(want).max() > 1.0   # the camera moves
    np.testing.assert_allclose(got[~big], want[~big], atol=2e-3, rtol=1e-4)
    np.testing.assert_allclose(got[big], want[big], rtol=1e-2)


@pytest.mark.parametrize("ortho", [False, True])
def test_camera_motion_fills_the_aov_and_the_blur_in_one_pass_as_two_passes_do(ortho):
    """seen_motion: one projection per pixel adds the AOV's rule to motion and the blur's
    (half_seen) to seen_motion, bit for bit what two passes add."""
    rng = np.random.default_rng(7)
    proj = Projection(orthographic=ortho, window=(-0.6, -0.45, 0.8, 0.5), near=0.1, far=1e4, width=W, height=H)
    depth = rng.uniform(0.5, 40, (H, W)).astype(np.float32)
    depth[rng.random((H, W)) < 0.2] = np.inf
    depth[:3, :3] = 0.05
    cfw = [turn_and_shift(rng.normal(0, 0.3), rng.normal(size=3), rng.normal(0, 0.4, 3)) for _ in range(3)]
    to_open, to_close = invert_affine(cfw[1]) @ cfw[0], invert_affine(cfw[1]) @ cfw[2]
    d = wp.array(depth.ravel(), dtype=float, device="cpu")
    base = [rng.normal(0, 2, (H * W, 2)).astype(np.float32) for _ in range(2)]
    apart = [wp.array(b, dtype=wp.vec2, device="cpu") for b in base]
    for buffer, half_seen in zip(apart, (False, True)):
        vb.camera_motion(d, buffer, proj, to_open, to_close, "cpu", half_seen=half_seen)
    together = [wp.array(b, dtype=wp.vec2, device="cpu") for b in base]
    vb.camera_motion(d, together[0], proj, to_open, to_close, "cpu", seen_motion=together[1])
    for a, b in zip(apart, together):
        np.testing.assert_array_equal(a.numpy(), b.numpy())
    if not ortho:   # points behind the eye at one end: the two rules differ there
        assert (apart[0].numpy() != apart[1].numpy()).any()


def test_camera_motion_of_the_dome_stops_where_it_turns_out_of_view():
    proj = Projection(orthographic=False, window=(-0.5, -0.5, 0.5, 0.5), near=0.1, far=100, width=W, height=H)
    depth = np.full((H, W), np.inf, np.float32)
    half_turn = turn_and_shift(np.pi * 0.6, np.array([0.0, 1.0, 0.0]), np.zeros(3))
    want = camera_motion_numpy(proj, depth, np.eye(4), half_turn)
    motion = wp.zeros(H * W, dtype=wp.vec2, device="cpu")
    vb.camera_motion(wp.array(depth.ravel(), dtype=float, device="cpu"), motion, proj, np.eye(4), half_turn, "cpu")
    got = motion.numpy().reshape(H, W, 2)
    gone = ~want.any(-1)
    assert 0 < gone.sum() < H * W   # part of the sky turns 90° or more away, part does not
    assert not got[gone].any()
    np.testing.assert_allclose(got, want, rtol=1e-4, atol=1e-2)


@pytest.mark.parametrize("radius", [0.0, 1.0, 2.0, 7.0])
def test_soft_edges_match_numpy(radius):
    v = random_velocity(np.random.default_rng(int(radius * 10)))
    want = 0.5 * soft_edge_numpy(v.astype(np.float64), radius)
    got = vb.soft_half_velocities(wp.array(v.reshape(-1, 2), dtype=wp.vec2, device="cpu"), W, H, radius, "cpu")
    got = got.numpy().reshape(H, W, 2)
    if radius > 0:
        spread = (np.linalg.norm(v, axis=-1) <= 1e-3) & (np.linalg.norm(want, axis=-1) > 0)
        assert spread.sum() > 20   # velocity reaches still pixels past the silhouettes
    np.testing.assert_allclose(got, want, atol=1e-5, rtol=1e-5)


@pytest.mark.parametrize("tile", [8, 13, 64])
def test_tile_and_neighbour_maxima_match_numpy(tile):
    vhalf = 0.5 * random_velocity(np.random.default_rng(tile))
    want, want_tx = neighbour_max_numpy(vhalf.astype(np.float64), tile)
    tmax, tx, ty = vb.tile_maxima(wp.array(vhalf.reshape(-1, 2), dtype=wp.vec2, device="cpu"), W, H, tile, "cpu")
    got = vb.neighbour_maxima(tmax, tx, ty, "cpu").numpy()
    assert tx == want_tx and got.shape == want.shape
    np.testing.assert_allclose(got, want, rtol=1e-6)
