"""Where float32 stands: the analytic method's coverage code run in float32 and in float64.

The renderer's kernels are float32 (positions made camera-relative in float64 on the host first).
The exact coverage times are where precision is most in doubt (quadratic roots of edge functions),
so `coverage_precision` samples (pixel, moving triangle) pairs of a real frame and runs the same
generic Warp functions (methods/analytic/coverage.py) on float32 inputs, as the renderer does, and
on float64 inputs, and reports the largest difference in covered shutter time.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
import warp as wp

from ..raster.binning import entry_pixel_bounds
from ..methods.analytic.coverage import DEGENERATE_TOL_F32, DEGENERATE_TOL_F64, coverage_times
from ..methods.analytic.segments import plan_motion
from ..usd.scene import Scene
from ..usd.stage import choose_camera, open_stage, projection_at, shutter_for_frame


@dataclass
class CoveragePrecision:
    """pairs: (pixel, moving entry) pairs compared; covered: pairs covered in float64 for some
    time; max_dt / mean_dt: |covered shutter time, float32 − float64| (fractions of the shutter);
    piece_mismatches: pairs whose number of covered pieces differs."""

    pairs: int
    covered: int
    max_dt: float
    mean_dt: float
    piece_mismatches: int

    def as_dict(self) -> dict:
        return asdict(self)


def _run(p0: np.ndarray, p1: np.ndarray, origin: np.ndarray, direction: np.ndarray, vi: np.ndarray,
         double: bool, device: str) -> tuple[np.ndarray, np.ndarray]:
    if double:
        vec, scalar, tol = wp.vec3d, wp.float64, DEGENERATE_TOL_F64
    else:
        vec, scalar, tol = wp.vec3, wp.float32, DEGENERATE_TOL_F32
    n = len(vi)
    covered = wp.zeros(n, dtype=scalar, device=device)
    pieces = wp.zeros(n, dtype=int, device=device)
    wp.launch(coverage_times, dim=n, device=device,
              inputs=[wp.array(p0, dtype=vec, device=device), wp.array(p1, dtype=vec, device=device),
                      wp.array(origin, dtype=vec, device=device), wp.array(direction, dtype=vec, device=device),
                      wp.array(vi.astype(np.int32), dtype=wp.vec3i, device=device), scalar(tol), covered, pieces])
    return covered.numpy().astype(np.float64), pieces.numpy()


def compare_coverage(p0: np.ndarray, p1: np.ndarray, origin: np.ndarray, direction: np.ndarray, vi: np.ndarray,
                     span: np.ndarray | None = None, device: str = "cpu") -> CoveragePrecision:
    """Cases (N): triangles p0 (N, 3, 3) moving to p1, rays origin + t direction (N, 3), all float64
    camera space; vertex indices vi (N, 3); span (N,) the shutter share of each case's span."""
    if len(vi) == 0:
        return CoveragePrecision(0, 0, 0.0, 0.0, 0)
    f32 = [np.asarray(a, np.float32) for a in (p0, p1, origin, direction)]
    c32, n32 = _run(*f32, vi, double=False, device=device)
    c64, n64 = _run(p0, p1, origin, direction, vi, double=True, device=device)
    scale = np.ones(len(vi)) if span is None else span
    dt = np.abs(c32 - c64) * scale
    return CoveragePrecision(int(len(vi)), int((c64 > 0).sum()), float(dt.max()), float(dt.mean()),
                             int((n32 != n64).sum()))


def coverage_precision(scene_path: str, frame: float, resolution: tuple[int, int], max_pairs: int = 20000,
                       seed: int = 0, device: str = "cpu") -> CoveragePrecision:
    """Float32 vs float64 coverage of up to max_pairs (pixel, moving triangle segment) pairs of a
    frame: each pair is a moving entry of the analytic method's motion plan and a pixel centre
    inside its swept screen box."""
    stage = open_stage(scene_path)
    cam = choose_camera(stage, None)
    proj = projection_at(cam, frame, resolution)
    shutter = shutter_for_frame(stage, cam, frame, None)
    scene = Scene(stage, cam, frame, shutter)
    plan = plan_motion(scene, proj, shutter.time)
    moving = np.nonzero(plan.entry_k0 != plan.entry_k1)[0]
    if len(moving) == 0:
        return CoveragePrecision(0, 0, 0.0, 0.0, 0)
    boxes, keep = entry_pixel_bounds(proj, plan.positions, scene.tri_vertices, plan.entry_tri[moving],
                                     plan.entry_k0[moving], plan.entry_k1[moving], 0.0)
    moving, boxes = moving[keep], boxes[keep]
    rng = np.random.default_rng(seed)
    pick = rng.choice(len(moving), size=min(max_pairs, len(moving) * 4), replace=len(moving) * 4 > len(moving))
    e, b = moving[pick], boxes[pick]
    w, h = resolution
    x = np.floor(rng.uniform(np.clip(b[:, 0], 0, w - 1), np.clip(b[:, 2], 0, w - 1) + 1)).clip(0, w - 1) + 0.5
    y = np.floor(rng.uniform(np.clip(b[:, 1], 0, h - 1), np.clip(b[:, 3], 0, h - 1) + 1)).clip(0, h - 1) + 0.5
    wx, wy = proj.pixel_window_coords(x, y)
    if proj.orthographic:
        origin = np.stack([wx, wy, np.zeros_like(wx)], 1)
        direction = np.tile([0.0, 0.0, -1.0], (len(e), 1))
    else:
        origin = np.zeros((len(e), 3))
        direction = np.stack([wx, wy, -np.ones_like(wx)], 1)
    vi = scene.tri_vertices[plan.entry_tri[e]]
    k0, k1 = plan.entry_k0[e], plan.entry_k1[e]
    p0 = plan.positions[k0[:, None], vi]
    p1 = plan.positions[k1[:, None], vi]
    span = (k1 - k0) / (len(plan.positions) - 1)
    return compare_coverage(p0, p1, origin, direction, vi, span, device)
