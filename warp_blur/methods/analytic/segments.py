"""Motion segments: each prim's motion over the shutter as piecewise-linear camera-space paths.

Vertices follow USD's true paths (rotations are arcs). The shutter is sampled at M+1 fine knots
(M = max_segments); each prim gets the fewest segments K (a power of two dividing M) such that no
vertex is more than `error_px` pixels on screen from where USD puts it, at every fine knot, nor
more than `time_error` × its own screen path length (an edge that moves slowly on screen turns a
small position error into a large error in the time it covers a pixel: this keeps coverage-time
errors near `time_error`), and at least motion:nonlinearSampleCount - 1 segments when its motion
is not linear. A prim that does not
move (in camera space) gets one static entry and no prism work.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pxr import UsdGeom

from ...camera import Projection
from ...scene import Scene


@dataclass
class MotionPlan:
    """Knots kept for the frame and the entries (triangle, knot span) to render.

    positions: (K+1, V, 3) float64 camera space at u = k/K; normals likewise (or None);
    lights: (K+1, NL, LIGHT_WIDTH); entry_*: (E,) int32; segments_per_prim: path -> K_p (0 = static).
    """

    positions: np.ndarray
    normals: np.ndarray | None
    lights: np.ndarray
    entry_tri: np.ndarray
    entry_k0: np.ndarray
    entry_k1: np.ndarray
    segments_per_prim: dict
    max_error_px: float
    lights_static: bool

    @property
    def num_segments(self) -> int:
        return self.positions.shape[0] - 1


def screen_distance_px(proj: Projection, p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Screen distance (pixels) between camera-space points, elementwise over (..., 3).

    Points in front of the near plane are measured as if at the near plane (conservative)."""
    if proj.orthographic:
        return np.linalg.norm((p - q)[..., :2], axis=-1) * proj.pixels_per_unit
    depth = np.maximum(np.minimum(-p[..., 2], -q[..., 2]), proj.near)
    return np.linalg.norm(p - q, axis=-1) / depth * proj.pixels_per_unit


def screen_error_px(proj: Projection, truth: np.ndarray, approx: np.ndarray) -> float:
    """Largest screen distance (pixels) between true and approximated camera-space points."""
    if truth.size == 0:
        return 0.0
    return float(screen_distance_px(proj, truth, approx).max())


def _hint(prim) -> int:
    try:
        return int(UsdGeom.MotionAPI(prim).ComputeNonlinearSampleCount())
    except Exception:
        return 3


def plan_motion(scene: Scene, proj: Projection, shutter_time, max_segments: int = 16,
                error_px: float = 0.25, time_error: float = 0.01) -> MotionPlan:
    """Sample the shutter and choose segments per prim. shutter_time(u) -> USD time."""
    instant = shutter_time(0.0) == shutter_time(1.0)
    m = 1 if instant else max_segments
    snaps = [scene.snapshot(shutter_time(k / m)) for k in range(m + 1)]
    fine = np.stack([s.positions for s in snaps])                       # (M+1, V, 3)
    lights_fine = np.stack([s.lights for s in snaps])
    lights_static = bool(np.all(lights_fine == lights_fine[:1]))
    seg_of_unit = []
    max_err = 0.0
    for ui, unit in enumerate(scene.units):
        o = scene.unit_vertex_offsets[ui]
        p = fine[:, o:o + unit.num_points * unit.num_instances]
        if instant or np.array_equal(p, np.broadcast_to(p[:1], p.shape)):
            seg_of_unit.append(0)
            continue
        chosen, err = m, 0.0
        path_px = screen_distance_px(proj, p[1:], p[:-1]).sum(axis=0)        # (N,) screen path length
        allowed = np.maximum(np.minimum(error_px, time_error * path_px), 1e-3)
        k = 1
        while k <= m:
            stride = m // k
            knots = p[::stride]
            f = (np.arange(m + 1) % stride) / stride
            lo = knots[np.minimum(np.arange(m + 1) // stride, k - 1)]
            hi = knots[np.minimum(np.arange(m + 1) // stride + 1, k)]
            f = np.where(np.arange(m + 1) == m, 1.0, f)[:, None, None]
            lo = np.where(np.arange(m + 1)[:, None, None] == m, knots[k - 1], lo)
            approx = lo + f * (hi - lo)
            dev = screen_distance_px(proj, p, approx).max(axis=0)
            err = float(dev.max()) if dev.size else 0.0
            if (dev <= allowed).all():
                chosen = k
                break
            k *= 2
        if chosen > 1:  # not linear: honour the prim's nonlinear sample count hint
            hint = _hint(unit.prim) - 1
            while chosen < min(hint, m):
                chosen *= 2
        max_err = max(max_err, err)
        seg_of_unit.append(chosen)
    k_global = max(seg_of_unit + [1])
    stride = m // k_global
    keep = np.arange(0, m + 1, stride)
    positions = fine[keep]
    normals = np.stack([snaps[i].normals for i in keep]) if scene.any_smooth else None
    lights = lights_fine[keep]
    tri_e, k0_e, k1_e = [], [], []
    tri_ids = np.arange(scene.num_triangles, dtype=np.int32)
    vis = np.stack([snaps[i].tri_visible for i in keep]) if scene.num_triangles else np.zeros((len(keep), 0), bool)
    for ui, k in enumerate(seg_of_unit):
        tris = tri_ids[scene.tri_unit == ui]
        if k == 0:
            tris = tris[vis[0, tris]]
            tri_e.append(tris)
            k0_e.append(np.zeros(len(tris), np.int32))
            k1_e.append(np.zeros(len(tris), np.int32))
            continue
        step = k_global // k
        for s in range(k):
            a, b = s * step, (s + 1) * step
            t = tris[vis[a, tris]]  # visibility of a segment is that at its start
            tri_e.append(t)
            k0_e.append(np.full(len(t), a, np.int32))
            k1_e.append(np.full(len(t), b, np.int32))
    cat = lambda a: np.concatenate(a).astype(np.int32) if a else np.zeros(0, np.int32)  # noqa: E731
    return MotionPlan(positions=positions, normals=normals, lights=lights, entry_tri=cat(tri_e),
                      entry_k0=cat(k0_e), entry_k1=cat(k1_e),
                      segments_per_prim={u.path: k for u, k in zip(scene.units, seg_of_unit)},
                      max_error_px=max_err, lights_static=lights_static)
