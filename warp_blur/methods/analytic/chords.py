"""The motion planner's per-vertex screen distances as float64 kernels over bands of vertices.

segments.plan_motion measures, for every vertex of the prims that move, its screen path over the
probes (its error tolerance) and how far each candidate segment's chord strays from USD's true
position at the check points. In NumPy each measurement was ~10 passes over (V, 3) arrays and a
gathered copy of the positions; with 1000 particle spheres (640 k vertices) the planner took
0.55 s of the frame, before the shadow maps could start. Here each is one pass that reads the
snapshots' arrays in place; below NUMPY_BELOW vertices the same formula runs in NumPy, whose few
passes over a few points cost less than a launch's set-up. tests/test_chords.py keeps the NumPy
form as the oracle.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ...core import warp_setup  # noqa: F401  (Warp's settings, before anything starts it)
from ...core.camera import Projection
from ...core.host_arrays import int32_array, vec3d_array
from ...core.parallel import launch_cheap


@wp.func
def screen_px(p: wp.vec3d, q: wp.vec3d, ortho: int, near: wp.float64, ppu: wp.float64) -> wp.float64:
    """Screen distance (pixels) between camera-space points p and q: perspective at the nearer
    depth, at least the near plane (conservative); inf where it is not a number."""
    d = p - q
    dist = wp.float64(0.0)
    if ortho != 0:
        dist = wp.sqrt(d[0] * d[0] + d[1] * d[1]) * ppu
    else:
        depth = wp.max(wp.min(-p[2], -q[2]), near)
        dist = wp.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) / depth * ppu
    if wp.isnan(dist):
        dist = wp.float64(wp.inf)
    return dist


@wp.kernel(enable_backward=False)
def add_screen_steps(a: wp.array(dtype=wp.vec3d), b: wp.array(dtype=wp.vec3d), ortho: int, near: wp.float64,
                     ppu: wp.float64, first: int,
                     # output
                     total: wp.array(dtype=wp.float64)):
    """total[v] += the screen distance from a[v] to b[v] (v = first + tid)."""
    v = first + wp.tid()
    total[v] = total[v] + screen_px(b[v], a[v], ortho, near, ppu)


@wp.kernel(enable_backward=False)
def max_chord_error(a: wp.array(dtype=wp.vec3d), b: wp.array(dtype=wp.vec3d), truth: wp.array(dtype=wp.vec3d),
                    idx: wp.array(dtype=wp.int32), f: wp.float64, ortho: int, near: wp.float64, ppu: wp.float64,
                    first: int,
                    # output
                    err: wp.array(dtype=wp.float64)):
    """err[i] = max(err[i], screen distance from truth to a + f (b - a)) at vertex idx[i]
    (i = first + tid)."""
    i = first + wp.tid()
    v = idx[i]
    pa = a[v]
    approx = pa + f * (b[v] - pa)
    err[i] = wp.max(err[i], screen_px(truth[v], approx, ortho, near, ppu))


#: vertices below which the planner's passes run in NumPy instead: a launch's set-up (array views of
#: the snapshots, argument packing, the pool) costs more than a few NumPy passes over so few points
#: (rotation's draft makes 37 checks a frame over 40 vertices: 74 µs each as launches)
NUMPY_BELOW = 4096


def screen_px_numpy(proj: Projection, p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """screen_px over (N, 3) float64 arrays of points, as the kernel computes it."""
    d = p - q
    with np.errstate(invalid="ignore", over="ignore"):
        if proj.orthographic:
            dist = np.sqrt(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1]) * proj.pixels_per_unit
        else:
            depth = np.maximum(np.minimum(-p[:, 2], -q[:, 2]), proj.near)
            dist = np.sqrt(np.einsum("ij,ij->i", d, d)) / depth * proj.pixels_per_unit
    return np.where(np.isnan(dist), np.inf, dist)


def _camera(proj: Projection) -> list:
    return [int(proj.orthographic), wp.float64(proj.near), wp.float64(proj.pixels_per_unit)]


def screen_path_px(proj: Projection, probes: list[np.ndarray], threads: int | None = None) -> np.ndarray:
    """(V,) each vertex's screen path (pixels) through the probes' positions ((V, 3) each, in order)."""
    n = len(probes[0])
    total = np.zeros(n, np.float64)
    if n < NUMPY_BELOW:
        for a, b in zip(probes, probes[1:]):
            total += screen_px_numpy(proj, np.asarray(b, np.float64), np.asarray(a, np.float64))
        return total
    out = wp.array(total, dtype=wp.float64, device="cpu", copy=False)
    for a, b in zip(probes, probes[1:]):
        fixed = [vec3d_array(a), vec3d_array(b), *_camera(proj)]
        launch_cheap(add_screen_steps, n, lambda first, _n: [*fixed, first, out], "cpu", threads)
    return total


def raise_chord_errors(proj: Projection, a: np.ndarray, b: np.ndarray, truth: np.ndarray, f: float,
                       idx: np.ndarray, err: np.ndarray, threads: int | None = None) -> None:
    """err (N,) float64 := max(err, the screen distance (pixels) between truth and a + f (b - a))
    at the vertices idx (N,) of the (V, 3) positions a, b and truth, in place."""
    if len(idx) == 0:
        return
    assert err.dtype == np.float64 and err.flags.c_contiguous
    if len(idx) < NUMPY_BELOW:
        pa = np.asarray(a, np.float64)[idx]
        approx = pa + f * (np.asarray(b, np.float64)[idx] - pa)
        np.maximum(err, screen_px_numpy(proj, np.asarray(truth, np.float64)[idx], approx), out=err)
        return
    out = wp.array(err, dtype=wp.float64, device="cpu", copy=False)
    fixed = [vec3d_array(a), vec3d_array(b), vec3d_array(truth), int32_array(idx), wp.float64(f), *_camera(proj)]
    launch_cheap(max_chord_error, len(idx), lambda first, _n: [*fixed, first, out], "cpu", threads)


#: how far a knot moves towards the inside of its vertex's curving path, as a fraction of its
#: chords' deviation from the path at their midpoints: a chord's distance from a smooth arc grows
#: as 4 d s (1 - s) along it (d at the midpoint), whose mean is 2d/3, so chords moved out by 2d/3
#: straddle the arc and are closest to it in the mean square (rotation's draft: RMSE 0.0017 ->
#: 0.00075 with the same segments; 1/2 and 3/4 measured 0.00085 and 0.00076)
STRADDLE = 2.0 / 3.0


def straddle_knots(positions: np.ndarray, spans_by_k: dict, mid_positions) -> None:
    """Move, in place, each curving vertex's knots so that its chords straddle its path instead of
    cutting inside it. positions: (K+1, V, 3) float64, the plan's knots at u = k/K; spans_by_k:
    segments k (dividing K) -> the vertex index arrays of the prims with k segments;
    mid_positions(k, j) -> (V, 3) USD's positions at the middle of segment j of k. A knot moves by
    STRADDLE × the mean of the mid-segment deviations (true minus chord) of the chords either side
    of it (the one chord at the shutter's ends), so neighbouring segments still meet; a vertex
    moving linearly (deviation below 1e-9 of its distance from the camera) keeps its knots exactly,
    as does one whose deviation is not a finite number."""
    k_all = positions.shape[0] - 1
    for k, idx in spans_by_k.items():
        if len(idx) == 0:
            continue
        step = k_all // k
        # one run of vertices (the usual case) is a slice: views, not gathered copies
        sel = slice(int(idx[0]), int(idx[-1]) + 1) if idx[-1] - idx[0] + 1 == len(idx) else idx
        knots = positions[::step, sel]                                      # (k+1, n, 3)
        with np.errstate(invalid="ignore", over="ignore"):
            dev = np.stack([mid_positions(k, j)[sel] for j in range(k)]) - 0.5 * (knots[:-1] + knots[1:])
            scale2 = np.einsum("kni,kni->kn", knots, knots).max(axis=0)     # (n,)
            dev2 = np.einsum("kni,kni->kn", dev, dev)
        # a point USD cannot place (not finite at a knot or midpoint) moves no knot
        linear = ~(dev2 > 1e-18 * scale2) | ~np.isfinite(dev2)
        if linear.all():
            continue
        dev[linear] = 0.0
        shift = np.empty_like(knots)
        shift[0], shift[-1] = dev[0], dev[-1]
        shift[1:-1] = 0.5 * (dev[:-1] + dev[1:])
        positions[::step, sel] = knots + STRADDLE * shift
