"""The entries' screen bounds kernel (raster/screen_bounds.py, through binning.entry_bounds)
against the NumPy forms it replaced (one core, float64), kept here as the oracle: boxes, keep
masks, swept slabs and nearest depths of moving, still, near-plane-crossing, behind-the-eye,
degenerate and orthographic entries."""

import numpy as np
import pytest

from warp_blur.core.camera import Projection
from warp_blur.raster import binning
from warp_blur.raster.binning import BAND_SLABS, clipped_hull_boxes, entry_bounds, entry_corners, pass_all_slabs


# ------------------------------------------------------------------ the NumPy forms (the oracle)
def entry_pixel_bounds_numpy(proj: Projection, positions: np.ndarray, tri_vertices: np.ndarray,
                             entry_tri: np.ndarray, entry_k0: np.ndarray, entry_k1: np.ndarray,
                             margin: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """binning.entry_pixel_bounds as it was (session 56)."""
    # vertex-major (6, E, ...) so the reductions over an entry's six points run along the first
    # axis (contiguous rows, ~40x faster than reducing a short middle axis)
    vi_t = tri_vertices[entry_tri].T                                    # (3, E)
    if len(entry_tri) and (entry_k0 == entry_k0[0]).all() and (entry_k1 == entry_k0[0]).all():
        # one knot for all (a sharp instant, a shadow map): each vertex projected once, then
        # gathered per corner (the same values as projecting the corners)
        knot = positions[entry_k0[0]]
        corners = lambda mask: knot[vi_t[:, mask]]                      # noqa: E731  (3, E', 3)
        depth = -knot[:, 2].astype(np.float64)[vi_t]
        with np.errstate(divide="ignore", invalid="ignore"):
            r = proj.project(knot)[vi_t]                                # (3, E, 2)
    else:
        pts = entry_corners(positions, tri_vertices, entry_tri, entry_k0, entry_k1)
        corners = lambda mask: pts[:3, mask]                            # noqa: E731
        depth = -pts[..., 2].astype(np.float64)                         # (6, E)
        with np.errstate(divide="ignore", invalid="ignore"):
            r = proj.project(pts)                                       # (6, E, 2)
    keep = ~((depth > proj.far).all(axis=0) | (depth < proj.near).all(axis=0))
    crosses = (depth < proj.near).any(axis=0) & (not proj.orthographic)
    # a NaN (0/0 at depth 0) only comes from an entry crossing the near plane: full box below
    lo = r.min(axis=0) - margin
    hi = r.max(axis=0) + margin
    box = np.concatenate([lo, hi], axis=1)
    still = crosses & (entry_k0 == entry_k1)
    if still.any():
        # a still entry crossing the near plane: the box of its part in front of the plane
        box[still] = clipped_hull_boxes(proj, corners(still), margin)
        crosses = crosses & ~still
    if crosses.any():
        # a moving one: its triangle stays inside the hull of its six vertices, so the box of the
        # hull's part in front of the plane (a ground running under a moving camera no longer
        # takes the whole screen)
        box[crosses] = clipped_hull_boxes(proj, pts[:, crosses], margin)
    finite = np.isfinite(box).all(axis=1)
    box[~finite] = (-margin, -margin, proj.width + margin, proj.height + margin)
    keep &= (box[:, 2] >= 0) & (box[:, 0] <= proj.width) & (box[:, 3] >= 0) & (box[:, 1] <= proj.height)
    return box, keep


def swept_bands_numpy(proj: Projection, positions: np.ndarray, tri_vertices: np.ndarray, entry_tri: np.ndarray,
                      entry_k0: np.ndarray, entry_k1: np.ndarray, margin: float = 1.0) -> np.ndarray:
    """binning.swept_bands as it was (session 56)."""
    moving = np.nonzero(entry_k0 != entry_k1)[0]
    out = pass_all_slabs(len(entry_tri), BAND_SLABS if len(moving) else 1)
    if len(moving) == 0:
        return out   # a sharp instant or a shadow map: the box test alone (slabs cost more than they save)
    pts = entry_corners(positions, tri_vertices, entry_tri[moving], entry_k0[moving], entry_k1[moving])
    depth = -pts[..., 2].astype(np.float64)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):   # behind the eye: not finite, no slabs
        r = proj.project(pts)                                           # (6, E, 2)
        motion = r[3:].mean(axis=0) - r[:3].mean(axis=0)                # (E, 2)
        length = np.hypot(motion[:, 0], motion[:, 1])
    finite = np.isfinite(r)
    ok = (finite[..., 0] & finite[..., 1]).all(axis=0)
    if not proj.orthographic:
        ok &= (depth >= proj.near).all(axis=0)
    if not ok.any():
        return out
    # compress keeps (6, E_ok, 2) C-ordered (r[:, ok] would not): the reductions over the six
    # points below then run along contiguous rows (~10x faster)
    r = np.compress(ok, r, axis=1)
    normals = [np.stack([-motion[ok, 1], motion[ok, 0]], axis=1)]      # across the motion
    for a, b in ((0, 1), (1, 2), (2, 0)):                               # each edge's normal at the start
        edge = r[b] - r[a]
        normals.append(np.stack([-edge[:, 1], edge[:, 0]], axis=1))
    travels = length[ok] > 2.0
    block = pass_all_slabs(len(travels), BAND_SLABS)                   # (E_ok, S, 4)
    for k, n in enumerate(normals):
        size = np.hypot(n[:, 0], n[:, 1])
        use = (size > 0.0) & np.isfinite(size) & (travels if k == 0 else True)
        with np.errstate(divide="ignore", invalid="ignore"):
            n = n / size[:, None]
        along = r[..., 0] * n[None, :, 0] + r[..., 1] * n[None, :, 1]   # (6, E_ok)
        slab = np.stack([n[:, 0], n[:, 1], along.min(axis=0) - margin, along.max(axis=0) + margin], axis=1)
        block[use, k] = slab[use]
    out[moving[ok]] = block
    return out


def entry_near_depth_numpy(positions, tri_vertices, entry_tri, entry_k0, entry_k1):
    return -entry_corners(positions, tri_vertices, entry_tri, entry_k0, entry_k1)[..., 2].max(axis=0)


# ------------------------------------------------------------------ inputs
def random_entries(rng: np.random.Generator, n: int, knots: int = 4):
    """positions (knots, V, 3) camera space, triangles and entries: most in front of the camera,
    some straddling the near plane or behind the eye, some still, some barely moving, degenerate
    ones, one vertex exactly at depth 0."""
    v = 3 * n
    base = rng.uniform(-4, 4, (v, 3))
    base[:, 2] = -rng.uniform(0.5, 30, v)
    positions = np.empty((knots, v, 3))
    for k in range(knots):
        positions[k] = base + k * rng.normal(0, 0.6, (v, 3)) * (rng.random((v, 1)) < 0.8)
    # near-plane crossings and points behind the eye
    cross = rng.choice(v, v // 10, replace=False)
    positions[:, cross, 2] = rng.uniform(-1.0, 0.3, (knots, len(cross)))
    positions[:, 0, 2] = 0.0                                     # at the eye's depth: 0/0 and x/0
    positions[:, 30:90, 2] = -60.0                               # triangles 10-29 beyond the far plane
    positions[:, 90:150, 0] += 400.0                             # triangles 30-49 off screen
    tri_vertices = np.arange(v).reshape(n, 3)
    tri_vertices[:5, 1] = tri_vertices[:5, 0]                    # degenerate: two corners the same
    entry_tri = rng.integers(0, n, 3 * n)
    k0 = rng.integers(0, knots, 3 * n)
    k1 = np.minimum(k0 + rng.integers(0, 2, 3 * n), knots - 1)  # still (k0 == k1) and moving spans
    return positions, tri_vertices, entry_tri.astype(np.int32), k0.astype(np.int32), k1.astype(np.int32)


@pytest.mark.parametrize("ortho", [False, True])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_entry_bounds_match_numpy(ortho, seed):
    rng = np.random.default_rng(seed)
    proj = Projection(orthographic=ortho, window=(-0.7, -0.5, 0.6, 0.55), near=0.1, far=25.0, width=97, height=71)
    positions, tri_vertices, entry_tri, k0, k1 = random_entries(rng, 400)
    box, keep, bands, near = entry_bounds(proj, positions, tri_vertices, entry_tri, k0, k1, 0.05)
    want_box, want_keep = entry_pixel_bounds_numpy(proj, positions, tri_vertices, entry_tri, k0, k1, 0.05)
    want_bands = swept_bands_numpy(proj, positions, tri_vertices, entry_tri, k0, k1, 0.05)
    want_near = entry_near_depth_numpy(positions, tri_vertices, entry_tri, k0, k1)
    assert (~want_keep).sum() > 50 and want_keep.sum() > 500          # both kinds are there
    assert (want_bands[:, 0, 2] != -1).sum() > 100                      # slabs in use
    np.testing.assert_array_equal(keep, want_keep)
    np.testing.assert_allclose(box[keep], want_box[keep], rtol=1e-12, atol=1e-9)
    np.testing.assert_array_equal(near, want_near)
    assert bands.shape == want_bands.shape == (len(entry_tri), BAND_SLABS, 4)
    np.testing.assert_allclose(bands, want_bands, rtol=1e-6, atol=1e-4)


@pytest.mark.parametrize("one_knot_kernel", [False, True])
@pytest.mark.parametrize("ortho", [False, True])
def test_entries_at_one_knot_and_still_entries_keep_the_box_alone(ortho, one_knot_kernel, monkeypatch):
    """One knot for all entries (a sharp instant, a shadow map: NumPy projects each vertex once
    for a few entries, the kernel runs at that knot alone for many) and still entries at several
    knots."""
    if one_knot_kernel:
        monkeypatch.setattr(binning, "ONE_KNOT_KERNEL_ENTRIES", 0)
    rng = np.random.default_rng(7)
    proj = Projection(orthographic=ortho, window=(-0.5, -0.5, 0.5, 0.5), near=0.1, far=50.0, width=64, height=48)
    positions, tri_vertices, entry_tri, _k0, _k1 = random_entries(rng, 200)
    for k0, k1 in [(np.full(len(entry_tri), 2, np.int32),) * 2,                       # one knot for all
                   (rng.integers(0, 4, len(entry_tri)).astype(np.int32),) * 2]:       # still, at several knots
        box, keep, bands, near = entry_bounds(proj, positions, tri_vertices, entry_tri, k0, k1, 0.05)
        want_box, want_keep = entry_pixel_bounds_numpy(proj, positions, tri_vertices, entry_tri, k0, k1, 0.05)
        np.testing.assert_array_equal(keep, want_keep)
        np.testing.assert_allclose(box[keep], want_box[keep], rtol=1e-12, atol=1e-9)
        np.testing.assert_array_equal(near, entry_near_depth_numpy(positions, tri_vertices, entry_tri, k0, k1))
        np.testing.assert_array_equal(bands, swept_bands_numpy(proj, positions, tri_vertices, entry_tri, k0, k1,
                                                               0.05))
