"""Each entry's screen footprint over its span, for binning (binning.py), as one float64 Warp
kernel over bands of entries on every core: the nearest depth of its six vertices (the tile
lists' sort key), the pixel box of their projections and the swept slabs (binning.swept_bands).

binning.py did this in NumPy on one core, gathering the six corners three times and keeping
(6, E, ...) temporaries: 0.25 s a frame for 288 k entries (3000 spinning cubes), a quarter of
the frame. The kernel computes what the NumPy did, in the same float64 operations;
tests/test_screen_bounds.py holds it to the NumPy forms.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ..core import warp_setup  # noqa: F401  (Warp's settings, before anything starts it)
from ..core.camera import Projection
from ..core.host_arrays import int32_array, vec3d_array, vec3i_array
from ..core.parallel import launch_pixels

#: entry flags: some vertex is in front of the far plane and some beyond the near plane (else
#: nothing of it can show); a vertex lies in front of the near plane (perspective: its box is the
#: clipped hull's, found on the host)
DEPTH_KEEP = 1
CROSSES_NEAR = 2
#: screen motion (pixels) below which the across-motion slab is not used (binning.swept_bands)
TRAVEL_PX = 2.0


@wp.func
def raster_point(p: wp.vec3d, window: wp.vec4d, width: wp.float64, height: wp.float64, ortho: int) -> wp.vec2d:
    """Raster position (pixels, x right, y down) of camera-space point p: Projection.project."""
    wx = p[0]
    wy = p[1]
    if ortho == 0:
        depth = -p[2]
        wx = p[0] / depth
        wy = p[1] / depth
    return wp.vec2d((wx - window[0]) / (window[2] - window[0]) * width,
                    (window[3] - wy) / (window[3] - window[1]) * height)


@wp.func
def finite2(r: wp.vec2d) -> bool:
    return wp.isfinite(r[0]) and wp.isfinite(r[1])


@wp.func
def slab_along(n: wp.vec2d, r0: wp.vec2d, r1: wp.vec2d, r2: wp.vec2d, r3: wp.vec2d, r4: wp.vec2d, r5: wp.vec2d,
               use: bool, margin: wp.float64) -> wp.vec4f:
    """The slab (nx, ny, lo, hi) along direction n (any length) holding the six points, widened by
    margin; the pass-all slab (0, 0, -1, 1) where not `use` or n has no finite, non-zero length."""
    size = wp.sqrt(n[0] * n[0] + n[1] * n[1])
    if not (use and size > wp.float64(0.0) and wp.isfinite(size)):
        return wp.vec4f(0.0, 0.0, -1.0, 1.0)
    u = wp.vec2d(n[0] / size, n[1] / size)
    a0 = r0[0] * u[0] + r0[1] * u[1]
    a1 = r1[0] * u[0] + r1[1] * u[1]
    a2 = r2[0] * u[0] + r2[1] * u[1]
    a3 = r3[0] * u[0] + r3[1] * u[1]
    a4 = r4[0] * u[0] + r4[1] * u[1]
    a5 = r5[0] * u[0] + r5[1] * u[1]
    lo = wp.min(wp.min(wp.min(a0, a1), wp.min(a2, a3)), wp.min(a4, a5))
    hi = wp.max(wp.max(wp.max(a0, a1), wp.max(a2, a3)), wp.max(a4, a5))
    return wp.vec4f(wp.float32(u[0]), wp.float32(u[1]), wp.float32(lo - margin), wp.float32(hi + margin))


@wp.kernel(enable_backward=False)
def entry_screen_bounds(positions: wp.array2d(dtype=wp.vec3d), tri_vertices: wp.array(dtype=wp.vec3i),
                        entry_tri: wp.array(dtype=wp.int32), entry_k0: wp.array(dtype=wp.int32),
                        entry_k1: wp.array(dtype=wp.int32), window: wp.vec4d, width: wp.float64,
                        height: wp.float64, near: wp.float64, far: wp.float64, ortho: int, margin: wp.float64,
                        with_slabs: int, first: int,
                        # outputs
                        near_depth: wp.array(dtype=wp.float64), boxes: wp.array(dtype=wp.vec4d),
                        flags: wp.array(dtype=wp.int8), slabs: wp.array2d(dtype=wp.vec4f)):
    """For entry i = first + tid (its triangle's vertices at knots entry_k0[i] and entry_k1[i]):
    near_depth[i], the nearest view depth of the six; boxes[i], the pixel box of their projections
    widened by margin (NaN where a projection is not finite); flags[i] (DEPTH_KEEP, CROSSES_NEAR);
    and, with with_slabs, slabs[i] (binning.swept_bands' four: across the screen motion, then
    along each edge's normal at the start; pass-all where the entry holds still, barely moves,
    reaches in front of the near plane or projects to a non-finite point)."""
    i = first + wp.tid()
    vi = tri_vertices[entry_tri[i]]
    k0 = entry_k0[i]
    k1 = entry_k1[i]
    p0 = positions[k0, vi[0]]
    p1 = positions[k0, vi[1]]
    p2 = positions[k0, vi[2]]
    p3 = positions[k1, vi[0]]
    p4 = positions[k1, vi[1]]
    p5 = positions[k1, vi[2]]
    z_lo = wp.min(wp.min(wp.min(-p0[2], -p1[2]), wp.min(-p2[2], -p3[2])), wp.min(-p4[2], -p5[2]))
    z_hi = wp.max(wp.max(wp.max(-p0[2], -p1[2]), wp.max(-p2[2], -p3[2])), wp.max(-p4[2], -p5[2]))
    near_depth[i] = z_lo
    f = int(0)
    if not (z_lo > far or z_hi < near):
        f = f | DEPTH_KEEP
    crosses = ortho == 0 and z_lo < near
    if crosses:
        f = f | CROSSES_NEAR
    flags[i] = wp.int8(f)
    r0 = raster_point(p0, window, width, height, ortho)
    r1 = raster_point(p1, window, width, height, ortho)
    r2 = raster_point(p2, window, width, height, ortho)
    r3 = raster_point(p3, window, width, height, ortho)
    r4 = raster_point(p4, window, width, height, ortho)
    r5 = raster_point(p5, window, width, height, ortho)
    finite = finite2(r0) and finite2(r1) and finite2(r2) and finite2(r3) and finite2(r4) and finite2(r5)
    if finite:
        boxes[i] = wp.vec4d(wp.min(wp.min(wp.min(r0[0], r1[0]), wp.min(r2[0], r3[0])), wp.min(r4[0], r5[0])) - margin,
                            wp.min(wp.min(wp.min(r0[1], r1[1]), wp.min(r2[1], r3[1])), wp.min(r4[1], r5[1])) - margin,
                            wp.max(wp.max(wp.max(r0[0], r1[0]), wp.max(r2[0], r3[0])), wp.max(r4[0], r5[0])) + margin,
                            wp.max(wp.max(wp.max(r0[1], r1[1]), wp.max(r2[1], r3[1])), wp.max(r4[1], r5[1])) + margin)
    else:
        nan = wp.float64(wp.nan)
        boxes[i] = wp.vec4d(nan, nan, nan, nan)
    if with_slabs != 0:
        use = finite and k0 != k1 and not crosses
        third = wp.float64(1.0) / wp.float64(3.0)
        motion = (r3 + r4 + r5) * third - (r0 + r1 + r2) * third
        travels = wp.sqrt(motion[0] * motion[0] + motion[1] * motion[1]) > wp.float64(TRAVEL_PX)
        slabs[i, 0] = slab_along(wp.vec2d(-motion[1], motion[0]), r0, r1, r2, r3, r4, r5, use and travels, margin)
        slabs[i, 1] = slab_along(wp.vec2d(-(r1[1] - r0[1]), r1[0] - r0[0]), r0, r1, r2, r3, r4, r5, use, margin)
        slabs[i, 2] = slab_along(wp.vec2d(-(r2[1] - r1[1]), r2[0] - r1[0]), r0, r1, r2, r3, r4, r5, use, margin)
        slabs[i, 3] = slab_along(wp.vec2d(-(r0[1] - r2[1]), r0[0] - r2[0]), r0, r1, r2, r3, r4, r5, use, margin)


def screen_bounds(proj: Projection, positions: np.ndarray, tri_vertices: np.ndarray, entry_tri: np.ndarray,
                  entry_k0: np.ndarray, entry_k1: np.ndarray, margin: float, slabs: int,
                  threads: int | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
    """(near depth (E,) float64, boxes (E, 4) float64, flags (E,) int8, slabs (E, slabs, 4) float32
    or None when slabs is 0) of the entries (triangle, knots k0..k1 of positions (K+1, V, 3),
    camera space, float64); see entry_screen_bounds."""
    n = len(entry_tri)
    near = np.empty(n, np.float64)
    boxes = np.empty((n, 4), np.float64)
    flags = np.empty(n, np.int8)
    out_slabs = np.empty((n, slabs, 4) if slabs else (1, 1, 4), np.float32)   # unwritten without slabs
    if n == 0:
        return near, boxes, flags, (out_slabs if slabs else None)
    dev = "cpu"
    pos, tv = vec3d_array(positions, dev), vec3i_array(tri_vertices, dev)
    et, e0, e1 = int32_array(entry_tri, dev), int32_array(entry_k0, dev), int32_array(entry_k1, dev)
    outs = [wp.array(near, dtype=wp.float64, device=dev, copy=False),
            wp.array(boxes, dtype=wp.vec4d, device=dev, copy=False),
            wp.array(flags, dtype=wp.int8, device=dev, copy=False),
            wp.array(out_slabs, dtype=wp.vec4f, device=dev, copy=False)]
    window = wp.vec4d(*(float(c) for c in proj.window))
    args = [pos, tv, et, e0, e1, window, float(proj.width), float(proj.height), float(proj.near), float(proj.far),
            int(proj.orthographic), float(margin), int(slabs > 0)]
    launch_pixels(entry_screen_bounds, n, lambda first, _n: [*args, first, *outs], dev, threads)
    return near, boxes, flags, (out_slabs if slabs else None)
