"""UsdGeom.BasisCurves as camera-facing ribbons of their `widths`, tessellated so that every
method renders them as triangles (hair, rain, wires).

Each curve is sampled as USD defines it — linear, or cubic with the bezier, bspline or catmullRom
basis, nonperiodic, periodic or pinned (phantom end points 2·P0 − P1, as USD's pinned wrap adds
them) — at SAMPLES_PER_SEGMENT points per cubic segment (linear curves at their vertices). At
each sample the ribbon spans ± width / 2 across the curve, perpendicular to its tangent and to the
camera's viewing direction at the frame time; positions (and so the ribbon) follow the curve's
points at every shutter time, so a moving curve blurs like a mesh.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pxr import Usd, UsdGeom

from .points import derived_points_fn, facing_axes
from .values import array_value, value_count

SAMPLES_PER_SEGMENT = 8
DEFAULT_WIDTH = 1.0

#: cubic bases, row-vector form: point(t) = [t^3, t^2, t, 1] @ M @ [P0, P1, P2, P3]
BASES = {
    "bezier": np.array([[-1, 3, -3, 1], [3, -6, 3, 0], [-3, 3, 0, 0], [1, 0, 0, 0]], np.float64),
    "bspline": np.array([[-1, 3, -3, 1], [3, -6, 3, 0], [-3, 0, 3, 0], [1, 4, 1, 0]], np.float64) / 6.0,
    "catmullRom": np.array([[-1, 3, -3, 1], [2, -5, 4, -1], [-1, 0, 1, 0], [0, 2, 0, 0]], np.float64) / 2.0,
}


@dataclass(frozen=True)
class CurveLayout:
    """How the sample points of every curve are made from the control points (fixed for a frame).

    indices, weights: (S, 4) — sample s = sum_j weights[s, j] * P[indices[s, j]] over the control
    points followed by two phantom points per curve (pinned wraps); curve_of_sample: (S,) int;
    first_sample: (K + 1,) offsets of each curve's samples."""

    indices: np.ndarray
    weights: np.ndarray
    curve_of_sample: np.ndarray
    first_sample: np.ndarray


def _segment_rows(basis: np.ndarray, count: int) -> np.ndarray:
    """(count, 4) weights of a segment's 4 control points at `count` parameters in [0, 1]."""
    t = np.linspace(0.0, 1.0, count)
    return np.stack([t ** 3, t ** 2, t, np.ones_like(t)], axis=1) @ basis


def curve_layout(kind: str, basis_name: str, wrap: str, counts: np.ndarray) -> CurveLayout | None:
    """The sample weights of curves with vertex counts `counts`, or None when a count does not
    make a curve of this type (a linear curve of one point, a bezier curve whose count is not
    3n + 1, a cubic curve of fewer than 4 points)."""
    total = int(counts.sum())
    basis = BASES.get(basis_name, BASES["bezier"])
    step = 3 if basis_name == "bezier" else 1
    seg_rows = _segment_rows(basis, SAMPLES_PER_SEGMENT)
    indices, weights, curve_of, firsts = [], [], [], [0]
    offset = 0
    for k, n in enumerate(counts.astype(int)):
        idx = np.arange(offset, offset + n)
        offset += n
        if kind == "linear":
            if n < 2:
                return None
            ids = np.r_[idx, idx[:1]] if wrap == "periodic" else idx
            indices.append(np.repeat(ids[:, None], 4, axis=1))
            weights.append(np.tile([1.0, 0.0, 0.0, 0.0], (len(ids), 1)))
        else:
            if wrap == "periodic":
                ctrl, segments = np.r_[idx, idx[:3]], n // step
            elif wrap == "pinned" and basis_name != "bezier":
                ctrl = np.r_[total + 2 * k, idx, total + 2 * k + 1]       # phantom end points
                segments = len(ctrl) - 3
            else:
                ctrl, segments = idx, (n - 4) // step + 1
            if n < 4 or segments < 1 or (basis_name == "bezier" and wrap != "periodic" and (n - 4) % 3 != 0):
                return None
            for sg in range(segments):
                four = ctrl[sg * step:sg * step + 4]
                rows = seg_rows if sg == 0 else seg_rows[1:]              # shared end samples once
                indices.append(np.repeat(four[None], len(rows), axis=0))
                weights.append(rows)
        added = sum(len(w) for w in weights) - firsts[-1]
        curve_of += [k] * added
        firsts.append(firsts[-1] + added)
    if not indices:
        return None
    return CurveLayout(np.concatenate(indices).astype(np.int64), np.concatenate(weights),
                       np.asarray(curve_of, np.int64), np.asarray(firsts, np.int64))


def sample_positions(layout: CurveLayout, points: np.ndarray, counts: np.ndarray, wrap: str) -> np.ndarray:
    """(S, 3) curve samples from control points (C, 3); pinned curves get phantom points 2·P0 − P1
    and 2·P(n−1) − P(n−2)."""
    extra = np.zeros((2 * len(counts), 3))
    if wrap == "pinned":
        offset = 0
        for k, n in enumerate(counts.astype(int)):
            p = points[offset:offset + n]
            if n >= 2:
                extra[2 * k] = 2 * p[0] - p[1]
                extra[2 * k + 1] = 2 * p[-1] - p[-2]
            offset += n
    full = np.concatenate([points, extra])
    return np.einsum("sj,sjc->sc", layout.weights, full[layout.indices])


def ribbon_triangles(layout: CurveLayout) -> np.ndarray:
    """(2 (S − K), 3) int32 triangles over the ribbon vertices [left_i, right_i] of each sample."""
    tris = []
    for a, b in zip(layout.first_sample[:-1], layout.first_sample[1:]):
        for i in range(a, b - 1):
            l0, r0, l1, r1 = 2 * i, 2 * i + 1, 2 * i + 2, 2 * i + 3
            tris += [(l0, r0, r1), (l0, r1, l1)]
    return np.asarray(tris, np.int32).reshape(-1, 3)


def ribbon_vertices(samples: np.ndarray, widths: np.ndarray, layout: CurveLayout, towards_camera: np.ndarray,
                    fallback_side: np.ndarray) -> np.ndarray:
    """(2 S, 3) float64 ribbon vertices: each sample ± width/2 across its tangent, facing the camera."""
    tangent = np.zeros_like(samples)
    for a, b in zip(layout.first_sample[:-1], layout.first_sample[1:]):
        seg = samples[a:b]
        if len(seg) > 1:
            tangent[a:b] = np.gradient(seg, axis=0)
    side = np.cross(tangent, towards_camera[None])
    norm = np.linalg.norm(side, axis=1)
    ok = norm > 1e-12 * np.maximum(np.linalg.norm(tangent, axis=1), 1e-300)
    side = np.where(ok[:, None], side / np.where(ok, norm, 1.0)[:, None], fallback_side[None])
    half = (widths / 2.0)[:, None] * side
    return np.stack([samples - half, samples + half], axis=1).reshape(-1, 3)


def sample_widths(curves: UsdGeom.BasisCurves, time: Usd.TimeCode, layout: CurveLayout, num_points: int,
                  num_curves: int) -> np.ndarray | None:
    """(S,) widths at the samples: one for all, one per curve, or per control point (through the
    same weights); USD's default of 1 when unauthored; None when they fit none of these."""
    w = array_value(curves.GetWidthsAttr(), time, np.float64).reshape(-1)
    s = len(layout.curve_of_sample)
    if len(w) == 0:
        return np.full(s, DEFAULT_WIDTH)
    if not (np.isfinite(w).all() and (w >= 0).all()):
        return None
    if len(w) == 1:
        return np.full(s, w[0])
    if len(w) == num_curves:
        return w[layout.curve_of_sample]
    if len(w) == num_points:
        padded = np.r_[w, np.zeros(2 * num_curves)]
        return np.abs(np.einsum("sj,sj->s", layout.weights, padded[layout.indices]))
    return None


def curves_unit_fields(scene, prim: Usd.Prim, t: Usd.TimeCode) -> dict | None:
    """GeomUnit fields of a UsdGeom.BasisCurves prim as camera-facing ribbons (None: nothing to
    render, or dropped as invalid); `scene` is the usd.scene.Scene being built (it makes them
    double-sided)."""
    schema = UsdGeom.BasisCurves(prim)
    path = str(prim.GetPath())
    n = value_count(schema.GetPointsAttr(), t)
    counts = array_value(schema.GetCurveVertexCountsAttr(), t, np.int64)
    if n == 0 or len(counts) == 0:
        return None
    kind = str(schema.GetTypeAttr().Get(t) or "cubic")
    basis = str(schema.GetBasisAttr().Get(t) or "bezier")
    wrap = str(schema.GetWrapAttr().Get(t) or "nonperiodic")
    layout = curve_layout(kind, basis, wrap, counts) if counts.sum() == n and (counts > 0).all() else None
    if layout is None:
        scene._invalid(path, f"curveVertexCounts do not make {kind} {basis} {wrap} curves of its {n} points")
        return None
    widths = sample_widths(schema, t, layout, n, len(counts))
    if widths is None and scene._invalid(path, "widths do not match the curves or are not finite non-negative numbers"):
        return None
    control_at = scene._valid_points_fn(prim, n)
    if control_at is None:
        return None
    right, up = facing_axes(prim, scene.camera.GetPrim(), scene._xf_cache(scene.frame))
    towards_camera = np.cross(right, up)
    tris = ribbon_triangles(layout)
    # each ribbon triangle takes the colour of its curve (uniform/constant) or of its first sample
    first_vertex = tris[:, 0] // 2
    colour_index = layout.indices[first_vertex, 1 if kind != "linear" else 0]
    colour_index = np.minimum(colour_index, n - 1)
    material, flags, blur = scene._common(prim, t)
    colors, uvs, opacity = scene._surface_primvars(prim, t, material, np.repeat(colour_index[:, None], 3, axis=1),
                                         layout.curve_of_sample[first_vertex], None)
    return dict(
        path=path, prim=prim, local_tris=tris, num_points=2 * len(layout.curve_of_sample),
        points_at=derived_points_fn(control_at, lambda c: ribbon_vertices(sample_positions(layout, c, counts, wrap),
                                                                          widths, layout, towards_camera, right)),
        transforms_at=scene._prim_transform_fn(prim), num_instances=1, corner_colors=colors, corner_uvs=uvs, corner_opacity=opacity,
        material=material, flags=flags, blur_scale=blur, visibility_prims=[prim])
