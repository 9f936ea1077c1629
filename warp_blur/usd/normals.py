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

import threading
from typing import Callable

import numpy as np
import warp as wp
from pxr import Usd, UsdGeom

from ..core import warp_setup  # noqa: F401  (Warp's settings, before anything starts it)
from ..core.host_arrays import vec3d_array
from ..core.parallel import launch_cheap
from ..core.sorting import stable_argsort
from ..core.log import warn_once
from .values import array_value, unregistered

HARD_EDGE_COS = 0.999


def _source(prim: Usd.Prim):
    """(value getter time -> array or None, interpolation) of the mesh's authored normals, or None
    (also, with a warning, when they are authored with a type USD does not know)."""
    pv = UsdGeom.PrimvarsAPI(prim).GetPrimvar("normals")
    mesh = UsdGeom.Mesh(prim)
    attr = mesh.GetNormalsAttr()
    if pv and pv.HasAuthoredValue():
        found = (lambda time: pv.ComputeFlattened(Usd.TimeCode(time))), pv.GetInterpolation(), pv.GetAttr()
    elif attr and attr.HasAuthoredValue():
        found = (lambda time: attr.Get(Usd.TimeCode(time))), mesh.GetNormalsInterpolation(), attr
    else:
        return None
    if unregistered(found[2].Get(Usd.TimeCode.EarliestTime())):
        warn_once(f"normals:{prim.GetPath()}", f"{found[2].GetPath()} is authored with a type USD does not know; "
                                               f"rendering flat facets")
        return None
    return found


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
    indices = array_value(UsdGeom.Mesh(prim).GetFaceVertexIndicesAttr(), t, np.int64)

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
    indices = array_value(UsdGeom.Mesh(prim).GetFaceVertexIndicesAttr(), t, np.int64)
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


@wp.kernel(enable_backward=False)
def _face_normals(positions: wp.array(dtype=wp.vec3d), tris: wp.array(dtype=wp.vec3i), first: int,
                  # output
                  out: wp.array(dtype=wp.vec3d)):
    """out[t] = (b - a) × (c - a) of triangle t = first + tid, component by component as np.cross
    computes it."""
    t = first + wp.tid()
    v = tris[t]
    a = positions[v[0]]
    e = positions[v[1]] - a
    f = positions[v[2]] - a
    x0 = e[1] * f[2]
    x1 = e[2] * f[1]
    y0 = e[2] * f[0]
    y1 = e[0] * f[2]
    z0 = e[0] * f[1]
    z1 = e[1] * f[0]
    out[t] = wp.vec3d(x0 - x1, y0 - y1, z0 - z1)


@wp.kernel(enable_backward=False)
def _vertex_sums(face_normals: wp.array(dtype=wp.vec3d), offsets: wp.array(dtype=wp.int32),
                 faces: wp.array(dtype=wp.int32), first: int,
                 # output
                 out: wp.array(dtype=wp.vec3)):
    """out[v] = the normalised sum of the face normals of vertex v = first + tid's corners
    faces[offsets[v]:offsets[v + 1]], added in that order (np.bincount's), in float64, rounded to
    float32."""
    v = first + wp.tid()
    x = wp.float64(0.0)
    y = wp.float64(0.0)
    z = wp.float64(0.0)
    for i in range(offsets[v], offsets[v + 1]):
        n = face_normals[faces[i]]
        x = x + n[0]
        y = y + n[1]
        z = z + n[2]
    xx = x * x
    yy = y * y
    zz = z * z
    sq = xx + yy
    sq = sq + zz
    length = wp.max(wp.sqrt(sq), wp.float64(1.0e-30))
    out[v] = wp.vec3(wp.float32(x / length), wp.float32(y / length), wp.float32(z / length))


class SmoothNormals:
    """Area-weighted, normalised vertex normals of one triangle topology (tris (T, 3) over V
    vertices) at any positions, by two Warp kernels on the CPU: equal bit for bit to NumPy's
    np.cross, np.bincount and np.linalg.norm on the same float64 positions (tested), ~15× faster
    than them on a 70 k-triangle mesh. The corner lists (each vertex's corners in triangle order)
    are built once."""

    def __init__(self, tris: np.ndarray, num_vertices: int) -> None:
        self.num_vertices = num_vertices
        self.num_triangles = len(tris)
        idx = np.ascontiguousarray(tris, np.int32).ravel()
        order = stable_argsort(idx)   # each vertex's corners in the order bincount adds them
        offsets = np.zeros(num_vertices + 1, np.int32)
        np.cumsum(np.bincount(idx, minlength=num_vertices), out=offsets[1:])
        self._tris = wp.array(idx.reshape(-1, 3), dtype=wp.vec3i, device="cpu")
        self._offsets = wp.array(offsets, dtype=wp.int32, device="cpu")
        self._faces = wp.array((order // 3).astype(np.int32), dtype=wp.int32, device="cpu")

    def __call__(self, positions: np.ndarray) -> np.ndarray:
        """(V, 3) float32 normals at positions (V, 3) float64."""
        p = vec3d_array(positions)
        face = wp.empty(self.num_triangles, dtype=wp.vec3d, device="cpu")
        out = wp.empty(self.num_vertices, dtype=wp.vec3, device="cpu")
        # (bands on every core for a field of instances, one launch for a few thousand triangles)
        launch_cheap(_face_normals, self.num_triangles, lambda first, _n: [p, self._tris, first, face], "cpu")
        launch_cheap(_vertex_sums, self.num_vertices, lambda first, _n: [face, self._offsets, self._faces, first, out],
                     "cpu")
        return out.numpy()


_kept: list[tuple[np.ndarray, SmoothNormals]] = []   # the last few topologies' corner lists, newest last
_kept_lock = threading.Lock()
KEPT_TOPOLOGIES = 4


def smooth_normals_for(tris: np.ndarray, num_vertices: int) -> SmoothNormals:
    """A SmoothNormals of this topology: kept across calls (a renderer's frames rebuild the scene
    but keep its triangles; building the corner lists costs 3× a call on `large`)."""
    with _kept_lock:
        for i, (kept_tris, normals) in enumerate(_kept):
            if normals.num_vertices == num_vertices and np.array_equal(kept_tris, tris):
                _kept.append(_kept.pop(i))
                return normals
    normals = SmoothNormals(tris, num_vertices)
    with _kept_lock:
        _kept.append((np.array(tris, copy=True), normals))
        del _kept[:-KEPT_TOPOLOGIES]
    return normals


def vertex_normals(positions: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """(V, 3) float32 area-weighted, normalised vertex normals of a triangle mesh (SmoothNormals,
    its corner lists kept per topology: smooth_normals_for)."""
    return smooth_normals_for(tris, len(positions))(positions)
