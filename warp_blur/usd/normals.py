"""Shading normals: smooth vertex normals of triangle meshes, and authored mesh normals (UsdGeom
`primvars:normals`, else `normals`) as per-point shading normals.

USD uses authored normals only on meshes that are not subdivided (subdivisionScheme "none"); a
subdivision surface's normals come from its limit surface. Interpolations:
- vertex / varying: one normal per point, as authored (indexed primvars flattened);
- faceVarying: one per face corner; where every corner at a point carries the same normal (the
  usual export of a smooth mesh) they are one per point; a mesh with hard edges (corners of a
  point that differ by more than HARD_EDGE_COS) has its points copied once per distinct normal
  (split_normals_fn), so each side of a hard edge keeps its own normals;
- uniform / constant: flat facets (what they say).
Normals move with the prim: the scene transforms them by each instant's inverse transpose.
"""

from __future__ import annotations

from typing import Callable

import numpy as np
from pxr import Usd, UsdGeom

from ..core.log import warn_once

HARD_EDGE_COS = 0.999


def _source(prim: Usd.Prim):
    """(value getter time -> array or None, interpolation) of the mesh's authored normals, or None."""
    pv = UsdGeom.PrimvarsAPI(prim).GetPrimvar("normals")
    if pv and pv.HasAuthoredValue():
        return (lambda time: pv.ComputeFlattened(Usd.TimeCode(time))), pv.GetInterpolation(), pv.GetAttr()
    mesh = UsdGeom.Mesh(prim)
    attr = mesh.GetNormalsAttr()
    if attr and attr.HasAuthoredValue():
        return (lambda time: attr.Get(Usd.TimeCode(time))), mesh.GetNormalsInterpolation(), attr
    return None


def _per_point(values: np.ndarray, interp: str, indices: np.ndarray, npts: int) -> np.ndarray | None:
    """(npts, 3) per-point normals from authored values, or None when they are not per point."""
    if interp in (UsdGeom.Tokens.vertex, UsdGeom.Tokens.varying):
        return values if len(values) == npts else None
    if interp != UsdGeom.Tokens.faceVarying or len(values) != len(indices):
        return None
    unit = values / np.maximum(np.linalg.norm(values, axis=1, keepdims=True), 1e-30)
    summed = np.zeros((npts, 3))
    np.add.at(summed, indices, unit)
    mean = summed / np.maximum(np.linalg.norm(summed, axis=1, keepdims=True), 1e-30)
    if (np.einsum("ij,ij->i", unit, mean[indices]) < HARD_EDGE_COS).any():
        return None
    return mean


def authored_normals_fn(prim: Usd.Prim, t: Usd.TimeCode, npts: int) -> Callable[[float], np.ndarray] | None:
    """time -> (npts, 3) float64 object-space normals of a non-subdivided mesh, or None when it has
    none that are per point (then it keeps flat facets; a warning says why when they were authored)."""
    src = _source(prim)
    if src is None:
        return None
    get, interp, attr = src
    path = str(prim.GetPath())
    indices = np.asarray(UsdGeom.Mesh(prim).GetFaceVertexIndicesAttr().Get(t) or [], np.int64)

    def at(time: float) -> np.ndarray | None:
        raw = get(time)
        if raw is None:
            return None
        values = np.asarray(raw, np.float64).reshape(-1, 3)
        if not np.isfinite(values).all():
            return None
        return _per_point(values, interp, indices, npts)

    first = at(float(t.GetValue()) if not t.IsDefault() else 0.0)
    if first is None:
        if interp == UsdGeom.Tokens.faceVarying:
            return None                 # hard edges: split_normals_fn
        if interp not in (UsdGeom.Tokens.uniform, UsdGeom.Tokens.constant):
            warn_once(f"normals:{path}", f"{path}: authored normals do not match the points; rendering flat facets")
        return None
    if attr.GetNumTimeSamples() <= 1:
        return lambda time, n=first: n

    def normals_at(time: float) -> np.ndarray:
        n = at(time)
        return first if n is None else n

    return normals_at


def split_normals_fn(prim: Usd.Prim, t: Usd.TimeCode, npts: int):
    """For faceVarying normals with hard edges: (source (N',) point of each new point, new point of
    each face corner (C,), time -> (N', 3) float64 normals), the mesh's points copied once per
    distinct normal at them (HARD_EDGE_COS apart, grouped at time t); None otherwise."""
    src = _source(prim)
    if src is None or src[1] != UsdGeom.Tokens.faceVarying:
        return None
    get, _, attr = src
    indices = np.asarray(UsdGeom.Mesh(prim).GetFaceVertexIndicesAttr().Get(t) or [], np.int64)
    time0 = float(t.GetValue()) if not t.IsDefault() else 0.0
    raw = get(time0)
    values = None if raw is None else np.asarray(raw, np.float64).reshape(-1, 3)
    if values is None or len(values) != len(indices) or not np.isfinite(values).all() or not len(indices):
        return None
    unit = values / np.maximum(np.linalg.norm(values, axis=1, keepdims=True), 1e-30)
    # a corner joins the first group at its point whose normal is within HARD_EDGE_COS (points
    # carry a handful of corners: a short loop over the few distinct normals each has)
    group = np.full(len(indices), -1, np.int64)
    order = np.argsort(indices, kind="stable")
    starts = np.r_[0, np.nonzero(np.diff(indices[order]))[0] + 1, len(order)]
    source: list[int] = []
    for a, b in zip(starts[:-1], starts[1:]):
        reps: list[int] = []
        for c in order[a:b]:
            for g, r in reps:
                if unit[c] @ unit[r] >= HARD_EDGE_COS:
                    group[c] = g
                    break
            else:
                group[c] = len(source)
                reps.append((len(source), c))
                source.append(int(indices[c]))
    source_arr = np.asarray(source, np.int64)
    rep = np.zeros(len(source_arr), np.int64)
    rep[group] = np.arange(len(indices))            # any corner of each group stands for it

    def normals_at(time: float) -> np.ndarray:
        raw_t = get(time) if attr.GetNumTimeSamples() > 1 else None
        vals = values if raw_t is None else np.asarray(raw_t, np.float64).reshape(-1, 3)
        if len(vals) != len(indices) or not np.isfinite(vals).all():
            vals = values
        return vals[rep]

    return source_arr, group, normals_at


def transform_normals(normals: np.ndarray, cam_from_local: np.ndarray) -> np.ndarray:
    """(I·N, 3) float32 unit camera-space normals of (N, 3) local normals under (I, 4, 4) row-vector
    transforms (the inverse transpose of each linear part)."""
    lin = cam_from_local[:, :3, :3]
    try:
        inv = np.linalg.inv(lin)
    except np.linalg.LinAlgError:   # an instance with a zero scale (collapsed: its normals are moot)
        inv = np.linalg.pinv(lin)
    inv_t = np.transpose(inv, (0, 2, 1))
    n = normals[None] @ inv_t                                     # (I, N, 3)
    n = n.reshape(-1, 3)
    return (n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)).astype(np.float32)


def vertex_normals(positions: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """(V, 3) float32 area-weighted, normalised vertex normals of a triangle mesh."""
    a, b, c = positions[tris[:, 0]], positions[tris[:, 1]], positions[tris[:, 2]]
    fn = np.cross(b - a, c - a)
    idx = tris.ravel()
    n = np.stack([np.bincount(idx, weights=np.repeat(fn[:, k], 3), minlength=len(positions))
                  for k in range(3)], axis=1)
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return (n / np.maximum(length, 1e-30)).astype(np.float32)


def vertex_normals_since(normals: np.ndarray, before: np.ndarray, positions: np.ndarray,
                         tris: np.ndarray) -> np.ndarray:
    """vertex_normals(positions, tris) given `normals` of the same mesh at positions `before`:
    only vertices sharing a triangle with a moved vertex are recomputed, from all their triangles
    in the same order, so the result is bit-identical to recomputing everything."""
    diff = positions != before
    moved = diff[:, 0] | diff[:, 1] | diff[:, 2]      # (short-axis any() is far slower)
    if not moved.any():
        return normals
    a, b, c = tris[:, 0], tris[:, 1], tris[:, 2]
    affected = np.zeros(len(positions), bool)
    affected[tris[moved[a] | moved[b] | moved[c]].ravel()] = True
    sub = tris[affected[a] | affected[b] | affected[c]]   # every triangle around an affected vertex
    fresh = vertex_normals(positions, sub)
    out = normals.copy()
    out[affected] = fresh[affected]
    return out
