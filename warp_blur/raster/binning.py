"""Screen-tile binning of entries on the host: which entries may cover which screen tile.

An entry's screen footprint over its time span is bounded by the projections of its vertices at
both ends (a linearly moving point projects to a straight screen segment while in front of the
eye). Entries with a vertex in front of the near plane at either end are given the box of the
part of their vertices' hull in front of it (their visible part is found per sample); entries
entirely beyond the far plane or entirely behind the near plane, or off screen, are dropped.
Moving entries' boxes, slabs and nearest depths come from one Warp kernel (screen_bounds.py);
the lists themselves from tile_lists.py's kernels.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.camera import Projection
from ..core.sorting import stable_argsort
from .screen_bounds import CROSSES_NEAR, DEPTH_KEEP, screen_bounds
from .tile_lists import tile_lists

TILE_SIZE = 16
#: Slack (pixels) around the camera's entry boxes and bands: kernels test them at sample points,
#: so it only absorbs float32 rounding between the host's float64 projection and the kernels'
#: camera-space tests (~1e-3 px at a thousand pixels). A whole pixel (the old margin) let ~30%
#: more entries through to the exact coverage test on `large` (20.1 vs 15.6 a sample), for nothing.
SAMPLE_MARGIN_PX = 0.05


@dataclass
class TileBins:
    tile_offsets: np.ndarray   # (num_tiles + 1,) int32
    tile_entries: np.ndarray   # (pairs,) int32, each tile's entries (ascending entry_near, or entry order)
    tiles_x: int
    tiles_y: int
    entry_boxes: np.ndarray | None = None   # (E, 4) float32 swept pixel boxes
    entry_bands: np.ndarray | None = None   # (E, S, 4) float32 swept slabs (nx, ny, lo, hi), see swept_bands
    #: (E,) a lower bound of each entry's view depth when every list runs in ascending order of it
    #: (bin_entries' near_depth), so a walk for the nearest hit may stop at the first entry beyond
    #: the hit it has; None: lists in entry order
    entry_near: np.ndarray | None = None

    @property
    def num_pairs(self) -> int:
        return len(self.tile_entries)

    def by_triangle(self, tris: np.ndarray, num_triangles: int) -> "TileBins":
        """These bins (of entries tris (E,), triangle indices) re-indexed in place so that every
        triangle of num_triangles is an entry: lists hold triangle indices, per-entry tables have a
        row per triangle (unlisted rows zero; their slabs pass every pixel)."""
        boxes = np.zeros((num_triangles, 4), np.float32)
        boxes[tris] = self.entry_boxes
        slabs = self.entry_bands.shape[1] if self.entry_bands is not None else 1
        bands = np.tile(np.array([0.0, 0.0, -1.0, 1.0], np.float32), (num_triangles, slabs, 1))
        if self.entry_bands is not None:
            bands[tris] = self.entry_bands
        self.tile_entries = tris[self.tile_entries].astype(np.int32)
        self.entry_boxes, self.entry_bands = boxes, bands
        if self.entry_near is not None:
            near = np.zeros(num_triangles, np.float32)
            near[tris] = self.entry_near
            self.entry_near = near
        return self


#: entries at one knot from which its bounds come from the screen-bounds kernel rather than NumPy
#: (below it, the kernel's launches cost more than NumPy's few calls: demo's accumulation-64 frame
#: +12%; above it NumPy's gathers cost more: a sharp pass over 1000 particle spheres' 1.2 M triangles)
ONE_KNOT_KERNEL_ENTRIES = 100_000


def entry_bounds(proj: Projection, positions: np.ndarray, tri_vertices: np.ndarray, entry_tri: np.ndarray,
                 entry_k0: np.ndarray, entry_k1: np.ndarray, margin: float = 1.0, slabs: bool = True,
                 threads: int | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray]:
    """(pixel boxes (E, 4) float64 [x0, y0, x1, y1], keep mask (E,), swept slabs (swept_bands;
    None unless `slabs`), nearest view depth (E,) of each entry's vertices over its span (the key
    that orders tile lists front first)) of the entries: triangle entry_tri[i] moving linearly
    between knots entry_k0[i] and entry_k1[i] of positions (K+1, V, 3), camera space."""
    if len(entry_tri) and (entry_k0 == entry_k0[0]).all() and (entry_k1 == entry_k0[0]).all():
        # one knot for all (a sharp instant, a shadow map): nothing moves, so the box test alone
        # (slabs cost more to compute and test than they save there: below, all-pass slabs)
        if len(entry_tri) < ONE_KNOT_KERNEL_ENTRIES:
            # each vertex projected once, then gathered per corner (the same values as projecting
            # the corners): a few NumPy calls, cheaper than the kernel's launches for a few entries
            box, keep, near = _one_knot_bounds(proj, positions[entry_k0[0]], tri_vertices, entry_tri, margin)
            return box, keep, (pass_all_slabs(len(entry_tri)) if slabs else None), near
        k = int(entry_k0[0])   # else the kernel, given that knot alone
        positions = positions[k:k + 1]
        entry_k0 = entry_k1 = np.zeros(len(entry_tri), np.int32)
    moving = bool((entry_k0 != entry_k1).any())
    near, box, flags, bands = screen_bounds(proj, positions, tri_vertices, entry_tri, entry_k0, entry_k1, margin,
                                            BAND_SLABS if slabs and moving else 0, threads)
    if slabs and not moving:
        bands = pass_all_slabs(len(entry_tri))
    keep = (flags & DEPTH_KEEP) != 0
    crosses = (flags & CROSSES_NEAR) != 0
    still = crosses & (entry_k0 == entry_k1)
    if still.any():
        # a still entry crossing the near plane: the box of its part in front of the plane
        box[still] = clipped_hull_boxes(proj, entry_corners(positions, tri_vertices, entry_tri[still],
                                                            entry_k0[still], entry_k1[still])[:3], margin)
    crosses &= ~still
    if crosses.any():
        # a moving one: its triangle stays inside the hull of its six vertices, so the box of the
        # hull's part in front of the plane (a ground running under a moving camera no longer
        # takes the whole screen)
        box[crosses] = clipped_hull_boxes(proj, entry_corners(positions, tri_vertices, entry_tri[crosses],
                                                              entry_k0[crosses], entry_k1[crosses]), margin)
    return box, _on_screen(proj, box, keep, margin), bands, near


def _one_knot_bounds(proj: Projection, knot: np.ndarray, tri_vertices: np.ndarray, entry_tri: np.ndarray,
                     margin: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """entry_bounds' boxes, keep mask and nearest depths where every entry is at one knot (V, 3)."""
    # vertex-major (3, E, ...) so the reductions over a triangle's corners run along the first
    # axis (contiguous rows, ~40x faster than reducing a short middle axis)
    vi_t = tri_vertices[entry_tri].T                                    # (3, E)
    depth = -knot[:, 2].astype(np.float64)[vi_t]
    with np.errstate(divide="ignore", invalid="ignore"):
        r = proj.project(knot)[vi_t]                                    # (3, E, 2)
    keep = ~((depth > proj.far).all(axis=0) | (depth < proj.near).all(axis=0))
    crosses = (depth < proj.near).any(axis=0) & (not proj.orthographic)
    # a NaN (0/0 at depth 0) only comes from an entry crossing the near plane: full box below
    box = np.concatenate([r.min(axis=0) - margin, r.max(axis=0) + margin], axis=1)
    if crosses.any():
        # crossing the near plane: the box of its part in front of the plane
        box[crosses] = clipped_hull_boxes(proj, knot[vi_t[:, crosses]], margin)
    return box, _on_screen(proj, box, keep, margin), depth.min(axis=0)


def _on_screen(proj: Projection, box: np.ndarray, keep: np.ndarray, margin: float) -> np.ndarray:
    """Boxes not finite become the whole screen (in place); keep, less boxes wholly off screen."""
    finite = np.isfinite(box).all(axis=1)
    box[~finite] = (-margin, -margin, proj.width + margin, proj.height + margin)
    return keep & (box[:, 2] >= 0) & (box[:, 0] <= proj.width) & (box[:, 3] >= 0) & (box[:, 1] <= proj.height)


def entry_pixel_bounds(proj: Projection, positions: np.ndarray, tri_vertices: np.ndarray,
                       entry_tri: np.ndarray, entry_k0: np.ndarray, entry_k1: np.ndarray,
                       margin: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Pixel bounding boxes (E, 4) float64 [x0, y0, x1, y1] and a keep mask (E,) of entries
    (entry_bounds' first two)."""
    box, keep, _, _ = entry_bounds(proj, positions, tri_vertices, entry_tri, entry_k0, entry_k1, margin, slabs=False)
    return box, keep


def entry_corners(positions: np.ndarray, tri_vertices: np.ndarray, entry_tri: np.ndarray, entry_k0: np.ndarray,
                  entry_k1: np.ndarray) -> np.ndarray:
    """(6, E, 3) the entries' three vertices at their span's start knot, then at its end knot,
    from positions (K+1, V, 3). One np.take over the flattened knots (~4x faster than indexing
    with a knot array and a vertex array)."""
    vi_t = tri_vertices[entry_tri].T                                    # (3, E)
    nv = positions.shape[1]
    index = np.concatenate([entry_k0[None, :] * nv + vi_t, entry_k1[None, :] * nv + vi_t], axis=0)
    return np.take(positions.reshape(-1, 3), index, axis=0)


#: slabs per entry (swept_bands): across its screen motion, then along each edge's normal
BAND_SLABS = 4


def pass_all_slabs(entries: int, slabs: int = 1) -> np.ndarray:
    """(entries, slabs, 4) float32 slabs (0, 0, -1, 1): every pixel passes (no slab reject)."""
    out = np.zeros((entries, slabs, 4), np.float32)
    out[..., 2], out[..., 3] = -1.0, 1.0
    return out


def swept_bands(proj: Projection, positions: np.ndarray, tri_vertices: np.ndarray, entry_tri: np.ndarray,
                entry_k0: np.ndarray, entry_k1: np.ndarray, margin: float = 1.0) -> np.ndarray:
    """(E, BAND_SLABS, 4) float32 slabs (nx, ny, lo, hi): every pixel an entry covers over its span
    has lo <= nx·x + ny·y <= hi in each. A moving triangle stays inside the convex hull of its six
    projected vertices (in front of the eye), so each slab over them is exact as a bound. Slab 0
    runs across the screen motion (the triangle's width where its box is the whole streak's: what
    rejects most of a long diagonal streak's box), slabs 1-3 along the normals of the triangle's
    edges at the span's start: with slab 0 they are the hexagon a translating triangle sweeps,
    which rejects the corners of its box. Slab 0 is (0, 0, -1, 1), no reject, for entries that
    barely move (< 2 px); all are for entries that hold still (their box is tested alone), cross
    the near plane or have no finite projection. When nothing moves (a sharp instant's pass, a
    shadow map) the result is one pass-all slab each, (E, 1, 4): there slabs cost more to compute
    and test than they save (accumulation's binning on `large` 0.42 -> 1.1 s for 16 instants)."""
    return entry_bounds(proj, positions, tri_vertices, entry_tri, entry_k0, entry_k1, margin)[2]


def clipped_hull_boxes(proj: Projection, pts: np.ndarray, margin: float) -> np.ndarray:
    """Pixel boxes (N, 4) of the convex hulls of K camera-space points each (K, N, 3; perspective)
    clipped to the near plane: the projections of the points in front of it and of the crossings
    of the plane by the segments between them (the clipped hull's corners are among those). A
    triangle (K = 3) crossing the plane of a shadow cube face or of a camera above a ground plane,
    or a moving triangle's six vertices (K = 6), would otherwise get the whole screen, and every
    tile would test it."""
    k = pts.shape[0]
    depth = -pts[..., 2]                                                   # (K, N)
    cand = [pts[i] for i in range(k)]
    ok = [depth[i] >= proj.near for i in range(k)]
    for i in range(k):
        for j in range(i + 1, k):
            di, dj = depth[i] - proj.near, depth[j] - proj.near
            with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
                s = di / (di - dj)
                cand.append(pts[i] + s[:, None] * (pts[j] - pts[i]))
            ok.append((di * dj < 0) & np.isfinite(s))
    cand = np.stack(cand)                                                  # (K + K(K-1)/2, N, 3)
    valid = np.stack(ok)
    # a crossing lies on the plane: give it the plane's depth exactly (no division by ~0)
    cand[k:, :, 2] = np.where(valid[k:], -max(proj.near, 1e-30), cand[k:, :, 2])
    with np.errstate(divide="ignore", invalid="ignore"):
        r = proj.project(cand)                                             # (C, N, 2)
    valid &= np.isfinite(r).all(axis=-1)
    lo = np.where(valid[..., None], r, np.inf).min(axis=0) - margin
    hi = np.where(valid[..., None], r, -np.inf).max(axis=0) + margin
    box = np.concatenate([lo, hi], axis=1)
    full = ~np.isfinite(box).all(axis=1)
    box[full] = (-margin, -margin, proj.width + margin, proj.height + margin)
    return box


def tile_mask_pixels(tiles: np.ndarray, tile_size: int, width: int, height: int) -> np.ndarray:
    """Flat pixel indices (ascending, int64) of the screen tiles set in `tiles` (tiles_y, tiles_x)
    bool, in an image of width × height."""
    mask = np.repeat(np.repeat(tiles, tile_size, axis=0), tile_size, axis=1)[:height, :width]
    return np.nonzero(mask.ravel())[0]


def bin_entries(proj: Projection, boxes: np.ndarray, keep: np.ndarray, tile_size: int = TILE_SIZE,
                near_depth: np.ndarray | None = None, bands: np.ndarray | None = None) -> TileBins:
    """Tile lists from entry pixel boxes (counted, written and scattered by tile_lists.py's kernels). Each
    tile lists its entries in entry order, or by ascending near_depth (E,) when given (a lower
    bound of each entry's view depth, ties by entry index: kernels walking a list meet the front
    surfaces first, and may stop at the first entry beyond what they hold). With swept
    slabs (E, S, 4) (swept_bands; (E, 4): one each), a tile that an entry's box reaches but one
    of its slabs misses does not list it: a diagonal streak's box holds many such tiles."""
    tiles_x = (proj.width + tile_size - 1) // tile_size
    tiles_y = (proj.height + tile_size - 1) // tile_size
    idx = np.nonzero(keep)[0]
    if near_depth is not None:
        idx = idx[stable_argsort(np.asarray(near_depth)[idx])]
    if bands is not None:
        bands = np.asarray(bands, np.float32)
        bands = bands[:, None] if bands.ndim == 2 else bands          # (E, 4): one slab each
    slabs = bands if bands is not None else np.zeros((1, 0, 4), np.float32)
    offsets, entries = tile_lists(boxes, idx, slabs, tile_size, tiles_x, tiles_y)
    near = None if near_depth is None else np.asarray(near_depth, np.float32)
    return TileBins(offsets, entries, tiles_x, tiles_y, np.asarray(boxes, np.float32), bands, near)
