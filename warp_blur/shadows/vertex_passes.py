"""Float64 passes over every vertex for the shadow maps' set-up, as kernels over bands of vertices:
what NumPy did in many passes over (V, 3) arrays, which a stage of 1000 particle spheres (640 k
vertices) made ~1 s of a frame on the thread that builds the maps: which vertices hold still in a
light's frame (direct.still_triangles), the faces' float32 positions at each map instant
(direct.FaceRasterizer), the scene's extreme vertices in 26 directions (casters.bounding_planes) and
a distant light's fit and stillness (maps.ShadowMaps._plan). Each equals its NumPy form
(tests/test_shadow_direct.py, tests/test_casters.py, tests/test_vertex_passes.py)."""

from __future__ import annotations

import itertools

import numpy as np
import warp as wp

from ..core import warp_setup  # noqa: F401  (Warp's settings, before anything starts it)
from ..core.host_arrays import int32_array, vec3d_array
from ..core.parallel import default_threads, launch_cheap, map_threads
from .layout import Sample

#: the 26 directions of a 3×3×3 grid: the scene's extreme vertices along them pre-test every plane
DIRECTIONS = np.array([d for d in itertools.product((-1.0, 0.0, 1.0), repeat=3) if any(d)])


def _band_cuts(n: int, threads: int | None) -> np.ndarray:
    """Bounds (B + 1,) of the bands a reduction over n items runs in, one launch each on the pool:
    one band under 64 k items, at most four per thread."""
    bands = max(1, min(n // 65536, 4 * (threads or default_threads())))
    return np.linspace(0, n, bands + 1).astype(np.int64)


@wp.kernel(enable_backward=False)
def light_local_change(ref: wp.array(dtype=wp.vec3d), probe: wp.array(dtype=wp.vec3d), o0: wp.vec3d, m0: wp.mat33d,
                       o1: wp.vec3d, m1: wp.mat33d, first: int,
                       # outputs
                       change: wp.array(dtype=wp.float64), size: wp.array(dtype=wp.float64)):
    """Vertex v = first + tid in a light's frame (origin o, rows of m its axes) at a reference
    probe and at another: change[v] = max(change[v], the largest coordinate difference; inf if not
    a number), size[v] = its largest reference coordinate (magnitude)."""
    v = first + wp.tid()
    l0 = m0 * (ref[v] - o0)
    d = m1 * (probe[v] - o1) - l0
    dmax = wp.max(wp.max(wp.abs(d[0]), wp.abs(d[1])), wp.abs(d[2]))
    if wp.isnan(dmax):
        dmax = wp.float64(wp.inf)
    change[v] = wp.max(change[v], dmax)
    size[v] = wp.max(wp.max(wp.abs(l0[0]), wp.abs(l0[1])), wp.abs(l0[2]))


def light_frame_changes(ref: np.ndarray, frame0: tuple[np.ndarray, np.ndarray],
                        others: list[tuple[np.ndarray, tuple[np.ndarray, np.ndarray]]], threads: int | None = None
                        ) -> tuple[np.ndarray, np.ndarray]:
    """((V,) the largest change of each vertex's light-frame coordinates from reference positions
    ref (V, 3) in frame0 (origin, axes) to each of `others` ((positions, frame) pairs; inf where
    not a number), (V,) each vertex's largest reference coordinate): direct.still_triangles' pass."""
    n = len(ref)
    change = np.zeros(n, np.float64)
    size = np.zeros(n, np.float64)
    if n == 0 or not others:
        return change, size
    dev = "cpu"
    outputs = [wp.array(change, dtype=wp.float64, device=dev, copy=False),
               wp.array(size, dtype=wp.float64, device=dev, copy=False)]
    o0, m0 = frame0
    ref_wp = vec3d_array(ref, dev)
    for positions, (o1, m1) in others:
        fixed = [ref_wp, vec3d_array(positions, dev), wp.vec3d(*o0), wp.mat33d(*np.ravel(m0)), wp.vec3d(*o1),
                 wp.mat33d(*np.ravel(m1))]
        launch_cheap(light_local_change, n, lambda first, _n: [*fixed, first, *outputs], dev, threads)
    return change, size


@wp.kernel(enable_backward=False)
def to_face_space(positions: wp.array(dtype=wp.vec3d), a: wp.mat33d, t: wp.vec3d, row: int, first: int,
                  # output
                  out: wp.array2d(dtype=wp.vec3)):
    """out[row, v] = a p + t in float32 for camera-space vertex p = positions[v] (v = first + tid):
    a face's positions at one instant, written where the splat reads them."""
    v = first + wp.tid()
    q = a * positions[v] + t
    out[row, v] = wp.vec3(wp.float32(q[0]), wp.float32(q[1]), wp.float32(q[2]))


def face_positions(transforms: list[tuple[np.ndarray, np.ndarray]], samples: list[Sample], rows: list[int],
                   times: int, device: str = "cpu", threads: int | None = None) -> wp.array:
    """(times, V) float32 face-space positions: row rows[i] = samples[i]'s positions through
    transforms[i] (A (3, 3), t (3,): q = A p + t), other rows 0. One kernel pass a row instead of
    NumPy's product, broadcast add and float32 copy (0.3 s a frame for 1000 particle spheres)."""
    num_v = max(max((len(s.positions) for s in samples), default=0), 1)
    out = wp.zeros((times, num_v), dtype=wp.vec3, device=device)
    for (a, t), s, row in zip(transforms, samples, rows):
        n = len(s.positions)
        if n == 0:
            continue
        fixed = [vec3d_array(s.positions, device),
                 wp.mat33d(*np.asarray(a, np.float64).ravel()), wp.vec3d(*np.asarray(t, np.float64)), int(row)]
        launch_cheap(to_face_space, n, lambda first, _n: [*fixed, first, out], device, threads)
    return out


@wp.kernel(enable_backward=False)
def band_support(points: wp.array(dtype=wp.vec3d), directions: wp.array(dtype=wp.vec3d), start: int, stop: int,
                 # outputs
                 best: wp.array(dtype=wp.float64), arg: wp.array(dtype=int)):
    """For direction tid: the largest d · p over points[start:stop] and the first index holding
    it (the band's share of `support`; -inf and -1 for an empty band)."""
    j = wp.tid()
    d = directions[j]
    top = wp.float64(-wp.inf)
    at = int(-1)
    for i in range(start, stop):
        p = points[i]
        v = p[0] * d[0] + p[1] * d[1] + p[2] * d[2]
        if v > top:
            top = v
            at = i
    best[j] = top
    arg[j] = at


def support(points: np.ndarray, threads: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(26,) the largest DIRECTIONS · p over points (U, 3) float64 and (26,) the first point index
    holding each, as NumPy's (DIRECTIONS @ points.T).max / .argmax (the products by ±1 and 0 are
    exact, so the sums are the same): bands of points on every core, without the (26, U)
    product, which cost 0.2 s a frame for 1000 particle spheres."""
    n, dev = len(points), "cpu"
    pts = vec3d_array(points, dev)
    dirs = wp.array(DIRECTIONS, dtype=wp.vec3d, device=dev)
    cuts = _band_cuts(n, threads)

    def band(k: int) -> tuple[np.ndarray, np.ndarray]:
        best = wp.empty(len(DIRECTIONS), dtype=wp.float64, device=dev)
        arg = wp.empty(len(DIRECTIONS), dtype=int, device=dev)
        wp.launch(band_support, dim=len(DIRECTIONS), inputs=[pts, dirs, int(cuts[k]), int(cuts[k + 1]), best, arg],
                  device=dev)
        return best.numpy(), arg.numpy()

    parts = map_threads(band, range(len(cuts) - 1), threads)
    best = np.stack([b for b, _ in parts])
    arg = np.stack([a for _, a in parts])
    first = best.argmax(axis=0)                        # the earliest band holding the maximum
    cols = np.arange(len(DIRECTIONS))
    return best[first, cols], arg[first, cols]


@wp.kernel(enable_backward=False)
def band_light_fit(ref: wp.array(dtype=wp.vec3d), ref_idx: wp.array(dtype=wp.int32), probe: wp.array(dtype=wp.vec3d),
                   probe_idx: wp.array(dtype=wp.int32), o0: wp.vec3d, m0: wp.mat33d, o1: wp.vec3d, m1: wp.mat33d,
                   compare: int, limit: wp.float64, start: int, stop: int,
                   # output
                   out: wp.array(dtype=wp.float64)):
    """Over points i in [start, stop) (one thread): light-local l = m1 (probe[probe_idx[i]] - o1);
    of those with every |coordinate| <= limit, out[0:3] the least and out[3:6] the greatest
    coordinates, out[6] the largest |coordinate| and out[7] how many; out[8] (compare = 1) the
    largest coordinate change from the reference m0 (ref[ref_idx[i]] - o0) (inf if not a number)."""
    inf = wp.float64(wp.inf)
    lo = wp.vec3d(inf, inf, inf)
    hi = wp.vec3d(-inf, -inf, -inf)
    top = wp.float64(0.0)
    count = wp.float64(0.0)
    change = wp.float64(0.0)
    for i in range(start, stop):
        l = m1 * (probe[probe_idx[i]] - o1)
        a = wp.max(wp.max(wp.abs(l[0]), wp.abs(l[1])), wp.abs(l[2]))
        if a <= limit:
            lo = wp.vec3d(wp.min(lo[0], l[0]), wp.min(lo[1], l[1]), wp.min(lo[2], l[2]))
            hi = wp.vec3d(wp.max(hi[0], l[0]), wp.max(hi[1], l[1]), wp.max(hi[2], l[2]))
            top = wp.max(top, a)
            count = count + wp.float64(1.0)
        if compare != 0:
            d = l - m0 * (ref[ref_idx[i]] - o0)
            dmax = wp.max(wp.max(wp.abs(d[0]), wp.abs(d[1])), wp.abs(d[2]))
            if wp.isnan(dmax):
                dmax = inf
            change = wp.max(change, dmax)
    for c in range(3):
        out[c] = lo[c]
        out[3 + c] = hi[c]
    out[6] = top
    out[7] = count
    out[8] = change


def light_fit(probes: list[tuple[np.ndarray, np.ndarray, tuple[np.ndarray, np.ndarray]]], limit: float,
              threads: int | None = None) -> tuple[np.ndarray, np.ndarray, float, int, float | None]:
    """A light's fit over its probes ((positions (V, 3), used vertex index (U,), light frame
    (origin, axes)) each): (least (3,) and greatest (3,) light-local coordinates and the largest
    |coordinate| of the points within `limit`, how many, the largest change of any point from the
    first probe's (None when the probes use different numbers of points))."""
    dev = "cpu"
    ref_pos, ref_idx, (o0, m0) = probes[0]
    indices: dict[int, wp.array] = {}   # each index array once (the probes mostly share one)

    def index_of(idx: np.ndarray) -> wp.array:
        if id(idx) not in indices:
            indices[id(idx)] = int32_array(idx, dev)
        return indices[id(idx)]

    ref_wp, ref_idx_wp = vec3d_array(ref_pos, dev), index_of(ref_idx)
    compare = all(len(idx) == len(ref_idx) for _, idx, _ in probes)
    rows = []
    for positions, idx, (o1, m1) in probes:
        cuts = _band_cuts(len(idx), threads)
        fixed = [ref_wp, ref_idx_wp, vec3d_array(positions, dev), index_of(idx), wp.vec3d(*o0),
                 wp.mat33d(*np.ravel(m0)), wp.vec3d(*o1), wp.mat33d(*np.ravel(m1)), int(compare), wp.float64(limit)]

        def band(k: int) -> np.ndarray:
            out = wp.empty(9, dtype=wp.float64, device=dev)
            wp.launch(band_light_fit, dim=1, inputs=[*fixed, int(cuts[k]), int(cuts[k + 1]), out], device=dev)
            return out.numpy()

        rows.extend(map_threads(band, range(len(cuts) - 1), threads))
    stats = np.stack(rows)
    return (stats[:, 0:3].min(axis=0), stats[:, 3:6].max(axis=0), float(stats[:, 6].max()), int(stats[:, 7].sum()),
            float(stats[:, 8].max()) if compare else None)
