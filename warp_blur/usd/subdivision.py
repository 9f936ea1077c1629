"""Catmull-Clark refinement of subdivision meshes (USD's default scheme) instead of their control
cage: each level is a sparse stencil S (refined points = S @ cage points), built once per
topology (kept across frames: mesh_refinement), so a deforming or moving cage is refined at every
shutter time by one matrix product.

Rules: face points are face centroids; interior edge points average the edge's ends and its two
faces' points; interior vertices move to (Q + 2R + (n − 3) P) / n; boundary edges and vertices
follow the boundary curve (3/4 P + 1/8 of each boundary neighbour), and a boundary vertex with two
edges is a corner that stays put (USD's `edgeAndCorner`). Semi-sharp creases and corners follow
DeRose et al. (1998): an edge of sharpness s ≥ 1 (boundaries always) takes the sharp rule (its
midpoint), 0 < s < 1 blends smooth and sharp by s, and its halves carry s − 1 to the next level; a
vertex on two creased edges follows the crease curve, on three or more (or with a corner
sharpness) stays put, blended by their mean sharpness below 1. Edges still sharp after the last
level (sharpness above the level count) shade hard: their points are copied per side, so smooth
normals do not blend across them. Meshes with holes, a left-handed
orientation or non-manifold edges are not refined (their cage is rendered, as before), nor are
point-instancer prototypes and skinned meshes. The level is capped for the
stage: the highest (up to MAX_LEVEL) at which all its subdivision meshes together stay within
SCENE_FACE_BUDGET faces; with the image known, each mesh takes the lowest level at which its faces
are about TARGET_FACE_PX across on screen (screen_level). Primvars are
carried per face corner, bilinearly within each cage face.
"""

from __future__ import annotations

import hashlib
import threading
from collections import OrderedDict
from dataclasses import dataclass

import numpy as np

from .loop import loop_refine
from .values import array_value, value_count

#: refine while every subdivision mesh of the stage together stays under this many faces (and at
#: most MAX_LEVEL levels): one level for the whole stage, so that its meshes look alike
SCENE_FACE_BUDGET = 100_000
MAX_LEVEL = 2
#: with the image known, a mesh is refined only until its faces are about this many pixels across
TARGET_FACE_PX = 4.0


@dataclass(frozen=True)
class Refinement:
    """stencil: (N', N) sparse cage -> refined points; quads: (F', 4) refined vertex indices
    ((F', 3) triangles for Loop); parent_face: (F',) cage face of each; corner_weights: (F', 4 or
    3, K) weights of each corner over its cage face's corners (K = the most corners of a cage
    face, zero-padded)."""

    stencil: sparse.csr_matrix
    quads: np.ndarray
    parent_face: np.ndarray
    corner_weights: np.ndarray
    levels: int


def _one_level(faces: list[np.ndarray], n: int, edge_sharpness: dict | None = None,
               vertex_sharpness: np.ndarray | None = None):
    """One Catmull-Clark level of polygons `faces` over n points, with semi-sharp creases
    (edge_sharpness: {(a, b) with a < b: sharpness}) and corners (vertex_sharpness (n,)): (stencil
    (n', n), quads (F', 4), (face, corner, k) of each quad's source, the child edges' and
    vertices' sharpness), or None for a non-manifold mesh."""
    from scipy import sparse   # (imported where used: ~0.13 s at start-up, for stages that subdivide)
    edge_sharpness = edge_sharpness or {}
    edge_id: dict[tuple[int, int], int] = {}
    edge_faces: list[list[int]] = []
    for f, fv in enumerate(faces):
        k = len(fv)
        for i in range(k):
            a, b = int(fv[i]), int(fv[(i + 1) % k])
            key = (a, b) if a < b else (b, a)
            if key not in edge_id:
                edge_id[key] = len(edge_faces)
                edge_faces.append([])
            edge_faces[edge_id[key]].append(f)
    if any(len(ef) > 2 for ef in edge_faces):
        return None
    nf, ne = len(faces), len(edge_faces)
    edges = np.array(list(edge_id.keys()), np.int64).reshape(-1, 2)
    sharp = np.array([float(edge_sharpness.get(key, 0.0)) for key in edge_id], np.float64)
    v_sharp = np.zeros(n) if vertex_sharpness is None else np.asarray(vertex_sharpness, np.float64)
    # face points
    rows = np.concatenate([np.full(len(fv), f) for f, fv in enumerate(faces)])
    cols = np.concatenate(faces)
    vals = np.concatenate([np.full(len(fv), 1.0 / len(fv)) for fv in faces])
    face_pts = sparse.csr_matrix((vals, (rows, cols)), shape=(nf, n))
    # edge points: smooth (ends and faces' points) blended towards the midpoint by the edge's
    # sharpness (sharp at >= 1, boundaries always)
    boundary = np.array([len(ef) == 1 for ef in edge_faces])
    w_sharp = np.where(boundary, 1.0, np.clip(sharp, 0.0, 1.0))
    mid = sparse.csr_matrix((np.full(2 * ne, 0.5), (np.repeat(np.arange(ne), 2), edges.ravel())), shape=(ne, n))
    ef_rows = [e for e, ef in enumerate(edge_faces) if len(ef) == 2 for _ in ef]
    ef_cols = [f for ef in edge_faces if len(ef) == 2 for f in ef]
    edge_face_avg = sparse.csr_matrix((np.full(len(ef_rows), 0.5), (ef_rows, ef_cols)), shape=(ne, nf))
    edge_pts = (sparse.diags(0.5 + 0.5 * w_sharp) @ mid
                + sparse.diags(0.5 * (1.0 - w_sharp)) @ (edge_face_avg @ face_pts))
    # vertex points
    v_faces = [[] for _ in range(n)]
    for f, fv in enumerate(faces):
        for v in fv:
            v_faces[int(v)].append(f)
    v_edges = [[] for _ in range(n)]
    for e, (a, b) in enumerate(edges):
        v_edges[a].append(e)
        v_edges[b].append(e)
    vr, vc, vv = [], [], []            # rows of (vertex, cage point, weight)
    fr, fc, fw = [], [], []            # rows of (vertex, face point, weight)

    def add(v: int, col: int, w: float, face: bool = False) -> None:
        (fr if face else vr).append(v)
        (fc if face else vc).append(col)
        (fw if face else vv).append(w)

    for v in range(n):
        es = v_edges[v]
        if not es:                      # a point no face uses: keep it
            add(v, v, 1.0)
            continue
        creased = [e for e in es if boundary[e] or sharp[e] > 0.0]
        if any(boundary[e] for e in es) and len(es) == 2:
            add(v, v, 1.0)              # a boundary corner (USD's edgeAndCorner)
            continue
        # the sharp rule and its weight: corner (>= 3 creased edges, or a corner sharpness), crease
        # (2 creased edges: the curve along them), else none; boundaries are infinitely sharp
        crease_mean = float(np.mean([np.inf if boundary[e] else sharp[e] for e in creased])) if creased else 0.0
        rule, weight = "smooth", 0.0
        if v_sharp[v] > 0.0 or len(creased) >= 3:
            rule, weight = "corner", max(v_sharp[v], crease_mean if len(creased) >= 3 else 0.0)
        elif len(creased) == 2:
            rule, weight = "crease", crease_mean
        weight = float(np.clip(weight, 0.0, 1.0))
        if weight > 0.0:
            if rule == "corner":
                add(v, v, weight)
            else:
                add(v, v, 0.75 * weight)
                for e in creased:
                    other = edges[e][0] if edges[e][1] == v else edges[e][1]
                    add(v, int(other), 0.125 * weight)
        smooth = 1.0 - weight
        if smooth > 0.0:
            k = len(es)
            for f in v_faces[v]:        # Q / k: the mean of the faces' points, over k
                add(v, f, smooth / (len(v_faces[v]) * k), face=True)
            for e in es:                # 2 R / k: edge midpoints' mean
                for w in edges[e]:
                    add(v, int(w), smooth * 2.0 * 0.5 / (k * k))
            add(v, v, smooth * (k - 3.0) / k)
    vert_pts = (sparse.csr_matrix((vv, (vr, vc)), shape=(n, n))
                + sparse.csr_matrix((fw, (fr, fc)), shape=(n, nf)) @ face_pts)
    stencil = sparse.vstack([vert_pts, edge_pts, face_pts]).tocsr()
    quads, sources = [], []
    for f, fv in enumerate(faces):
        k = len(fv)
        for i in range(k):
            a, b, p = int(fv[i]), int(fv[(i + 1) % k]), int(fv[i - 1])
            quads.append((a, n + edge_id[(min(a, b), max(a, b))], n + ne + f, n + edge_id[(min(p, a), max(p, a))]))
            sources.append((f, i, k))
    # children: each creased edge's two halves keep its sharpness less one, corners likewise
    child_edges = {}
    for e in np.nonzero(sharp > 1.0)[0]:
        a, b = int(edges[e][0]), int(edges[e][1])
        for end in (a, b):
            child_edges[(end, n + int(e))] = sharp[e] - 1.0
    child_vertices = np.zeros(n + ne + nf)
    child_vertices[:n] = np.maximum(v_sharp - 1.0, 0.0)
    return stencil, np.asarray(quads, np.int64), sources, child_edges, child_vertices


def crease_tables(mesh, time, num_points: int) -> tuple[dict, np.ndarray]:
    """A UsdGeom.Mesh's creases ({(a, b) with a < b: sharpness}, one sharpness per crease or per
    crease edge, as USD allows) and corners ((num_points,) sharpness)."""
    indices = array_value(mesh.GetCreaseIndicesAttr(), time, np.int64)
    lengths = array_value(mesh.GetCreaseLengthsAttr(), time, np.int64)
    sharpness = array_value(mesh.GetCreaseSharpnessesAttr(), time, np.float64)
    edges: dict = {}
    per_edge = len(sharpness) == int(np.maximum(lengths - 1, 0).sum()) and len(sharpness) != len(lengths)
    start, k = 0, 0
    for c, length in enumerate(lengths):
        chain = indices[start:start + length]
        for i in range(len(chain) - 1):
            s_val = sharpness[k] if per_edge and k < len(sharpness) else (sharpness[c] if c < len(sharpness) else 0.0)
            a, b = int(chain[i]), int(chain[i + 1])
            if 0 <= a < num_points and 0 <= b < num_points and a != b and np.isfinite(s_val):
                edges[(min(a, b), max(a, b))] = max(float(s_val), 0.0)
            k += 1
        start += int(length)
    corners = np.zeros(num_points)
    c_idx = array_value(mesh.GetCornerIndicesAttr(), time, np.int64)
    c_sharp = array_value(mesh.GetCornerSharpnessesAttr(), time, np.float64)
    for i, v in enumerate(c_idx):
        if 0 <= v < num_points and i < len(c_sharp) and np.isfinite(c_sharp[i]):
            corners[v] = max(corners[v], float(c_sharp[i]))
    return edges, corners


def _quad_corner_weights(i: int, k: int) -> np.ndarray:
    """(4, k) weights over a k-corner face's corners of sub-quad i's corners (corner, edge
    midpoint, centroid, previous edge midpoint): bilinear placement of face-corner primvars."""
    w = np.zeros((4, k))
    w[0, i] = 1.0
    w[1, i] += 0.5
    w[1, (i + 1) % k] += 0.5
    w[2, :] = 1.0 / k
    w[3, i] += 0.5
    w[3, (i - 1) % k] += 0.5
    return w


def stage_level(stage, time) -> int:
    """The refinement level of the stage's catmullClark meshes: the highest (<= MAX_LEVEL) at which
    their faces, four times more per level, stay within SCENE_FACE_BUDGET."""
    from pxr import Usd, UsdGeom
    faces = 0
    for prim in stage.Traverse(Usd.TraverseInstanceProxies(Usd.PrimDefaultPredicate)):
        if prim.IsA(UsdGeom.Mesh):
            mesh = UsdGeom.Mesh(prim)
            if mesh.GetSubdivisionSchemeAttr().Get(time) in (UsdGeom.Tokens.catmullClark, UsdGeom.Tokens.loop):
                counts = mesh.GetFaceVertexCountsAttr().Get(time)
                faces += int(np.sum(counts)) if counts is not None else 0   # refined faces: one per corner
    level = 0
    while level < MAX_LEVEL and faces * 4 ** level <= SCENE_FACE_BUDGET:
        level += 1
    return level


def screen_level(proj, local_points: np.ndarray, local_to_cam: np.ndarray, mesh, time: float, cap: int) -> int:
    """The level (1..cap) of subdivision mesh `mesh` (a UsdGeom.Mesh; its face corners are its
    level-1 faces) whose control points local_points (N, 3) go to camera space by local_to_cam
    (4, 4, row vectors) under projection proj (core.camera.Projection): the lowest at which its
    refined faces are at most TARGET_FACE_PX across over its on-screen box (the whole cap when a
    point is not in front of the near plane)."""
    counts = mesh.GetFaceVertexCountsAttr().Get(time)
    corners = int(np.sum(counts)) if counts is not None else 0
    cam_points = np.asarray(local_points, np.float64) @ local_to_cam[:3, :3] + local_to_cam[3, :3]
    if cap <= 1 or len(cam_points) == 0 or corners <= 0:
        return cap
    if not proj.orthographic and (-cam_points[:, 2] < proj.near).any():
        return cap
    r = proj.project(cam_points)
    if not np.isfinite(r).all():
        return cap
    w = np.clip(r[:, 0].max(), 0, proj.width) - np.clip(r[:, 0].min(), 0, proj.width)
    h = np.clip(r[:, 1].max(), 0, proj.height) - np.clip(r[:, 1].min(), 0, proj.height)
    area = max(float(w * h), 1.0)
    level = 1
    while level < cap and area / (corners * 4.0 ** (level - 1)) > TARGET_FACE_PX ** 2:
        level += 1
    return level


def refine(counts: np.ndarray, indices: np.ndarray, num_points: int, levels: int,
           creases: dict | None = None, corners: np.ndarray | None = None) -> Refinement | None:
    """`levels` Catmull-Clark levels of a cage (faceVertexCounts, faceVertexIndices over
    num_points), with crease_tables' creases and corners; None when the mesh cannot be refined
    here (non-manifold, degenerate faces) or levels is 0."""
    from scipy import sparse   # (imported where used: ~0.13 s at start-up, for stages that subdivide)
    if len(counts) == 0 or counts.min() < 3:
        return None
    offsets = np.r_[0, np.cumsum(counts)]
    faces = [indices[offsets[f]:offsets[f + 1]].astype(np.int64) for f in range(len(counts))]
    kmax = int(counts.max())
    stencil = sparse.identity(num_points, format="csr")
    parent = np.arange(len(faces))
    weights = np.zeros((len(faces), kmax, kmax))
    for f, fv in enumerate(faces):
        weights[f, :len(fv), :len(fv)] = np.eye(len(fv))      # corner j of face f = its own corner j
    level = 0
    n = num_points
    quads = None
    while level < levels:
        out = _one_level(faces, n, creases, corners)
        if out is None:
            return None
        s, quads, sources, creases, corners = out
        stencil = (s @ stencil).tocsr()
        new_weights = np.zeros((len(quads), 4, kmax))
        new_parent = np.empty(len(quads), np.int64)
        for q, (f, i, k) in enumerate(sources):
            new_weights[q] = _quad_corner_weights(i, k) @ weights[f, :k, :]
            new_parent[q] = parent[f]
        weights, parent = new_weights, new_parent
        faces = [row for row in quads]
        n = stencil.shape[0]
        level += 1
    if level == 0:
        return None
    if creases:                       # edges still sharp at this level: hard shading across them
        source, quads = split_at_creases(quads, creases, n)
        stencil = stencil[source]
    return Refinement(stencil, quads, parent, weights, level)


def split_at_creases(quads: np.ndarray, creases: dict, n: int) -> tuple[np.ndarray, np.ndarray]:
    """(source point (N'',), quads (F', 4)) with each of the n points copied once per fan of quads
    around it that its crease edges ({(a, b) with a < b: sharpness > 0}) separate, so smooth vertex
    normals stay on each side of a crease (hard shading, as the limit surface has there). The copies
    are the same point (same stencil row): positions stay bit-identical, the mesh watertight."""
    from scipy import sparse   # (imported where used: ~0.13 s at start-up, for stages that subdivide)
    from scipy.sparse import csgraph
    nq = len(quads)
    corner = np.arange(nq * 4).reshape(nq, 4)
    a, b = quads, np.roll(quads, -1, axis=1)                       # quad edge i runs a[:, i] -> b[:, i]
    lo, hi = np.minimum(a, b).ravel(), np.maximum(a, b).ravel()
    key = lo * np.int64(n) + hi
    sharp_keys = np.array([k0 * n + k1 for (k0, k1), s in creases.items() if s > 0.0], np.int64)
    smooth_edge = ~np.isin(key, sharp_keys)
    # the corners at each end of edge i: corner i (at a) and corner i+1 (at b)
    at_a, at_b = corner.ravel(), np.roll(corner, -1, axis=1).ravel()
    order = np.argsort(key, kind="stable")
    k_sorted = key[order]
    pair = np.nonzero(k_sorted[1:] == k_sorted[:-1])[0]           # interior edges: two quads share the key
    e1, e2 = order[pair], order[pair + 1]
    keep = smooth_edge[e1]
    e1, e2 = e1[keep], e2[keep]
    # opposite orientation in the two quads: e1's a-end is e2's b-end
    same_a = a.ravel()[e1] == a.ravel()[e2]
    u = np.concatenate([at_a[e1], at_b[e1]])
    v = np.concatenate([np.where(same_a, at_a[e2], at_b[e2]), np.where(same_a, at_b[e2], at_a[e2])])
    graph = sparse.coo_matrix((np.ones(len(u)), (u, v)), shape=(nq * 4, nq * 4))
    _, label = csgraph.connected_components(graph, directed=False)
    _, first, fan = np.unique(label, return_index=True, return_inverse=True)
    fan_point = quads.ravel()[first]                              # (fans,) the point each fan is at
    # each point's first fan keeps its index, the others are appended (a mesh without creases, or
    # a point on none, is numbered as before)
    order = np.lexsort((np.arange(len(fan_point)), fan_point))
    is_first = np.r_[True, fan_point[order][1:] != fan_point[order][:-1]]
    index = np.empty(len(fan_point), np.int64)
    index[order[is_first]] = fan_point[order[is_first]]
    extra = order[~is_first]
    index[extra] = n + np.arange(len(extra))
    source = np.concatenate([np.arange(n), fan_point[extra]]).astype(np.int64)
    return source, index[fan].reshape(nq, 4)


def refined_triangles(ref: Refinement) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(tris (2F', 3) int32, parent cage face (2F',), corner weights (2F', 3, K)) of the refined
    quads split along their 0-2 diagonal (a Loop refinement's triangles as they are)."""
    q = ref.quads
    if q.shape[1] == 3:
        return q.astype(np.int32), ref.parent_face, ref.corner_weights
    tris = np.stack([q[:, [0, 1, 2]], q[:, [0, 2, 3]]], axis=1).reshape(-1, 3).astype(np.int32)
    w = np.stack([ref.corner_weights[:, [0, 1, 2]], ref.corner_weights[:, [0, 2, 3]]], axis=1)
    return tris, np.repeat(ref.parent_face, 2), w.reshape(len(tris), 3, -1)


def refined_corner_primvar(prim, name: str, time, counts: np.ndarray, indices: np.ndarray, parent: np.ndarray,
                           weights: np.ndarray, width: int) -> np.ndarray | None:
    """(T', 3, width) float32 values of primvar `name` at the refined triangles' corners, placed
    bilinearly within each cage face from its values at the cage's face corners (any of USD's
    interpolations), or None when the prim has no such primvar (or corner_primvar refuses it)."""
    from .primvars import corner_primvar
    num_corners = len(indices)
    face_of_corner = np.repeat(np.arange(len(counts)), counts)
    fake_tris = np.repeat(indices.astype(np.int64)[:, None], 3, axis=1)
    positions = np.repeat(np.arange(num_corners)[:, None], 3, axis=1)
    per_corner = corner_primvar(prim, name, time, fake_tris, face_of_corner, positions, width)
    if per_corner is None:
        return None
    values = per_corner[:, 0, :].astype(np.float64)                    # (C, width)
    offsets = np.r_[0, np.cumsum(counts)][:-1]
    k = weights.shape[-1]
    idx = np.minimum(offsets[parent][:, None] + np.arange(k)[None], num_corners - 1)   # (T', K)
    return np.einsum("tcj,tjw->tcw", weights, values[idx]).astype(np.float32)


def _refinement_key(scheme, counts: np.ndarray, indices: np.ndarray, num_points: int, levels: int,
                    creases: dict, corners: np.ndarray) -> tuple:
    """What a refinement depends on (the topology, never the points): a digest of it."""
    h = hashlib.blake2b(digest_size=20)
    for a in (counts, indices, corners):
        h.update(np.ascontiguousarray(a).tobytes())
        h.update(b"|")
    h.update(repr(sorted(creases.items())).encode())
    return (str(scheme), int(num_points), int(levels), h.hexdigest())


def _refinement_bytes(ref: Refinement) -> int:
    st = ref.stencil
    return int(st.data.nbytes + st.indices.nbytes + st.indptr.nbytes + ref.quads.nbytes + ref.parent_face.nbytes
               + ref.corner_weights.nbytes)


def _remember(key: tuple, ref: Refinement | None) -> None:
    """Keep a refinement for the frames after this one (read-only: frames share it), the most
    recently used within REFINEMENT_CACHE_BYTES."""
    if ref is not None:
        for a in (ref.quads, ref.parent_face, ref.corner_weights):
            a.setflags(write=False)
    with _REFINEMENTS_LOCK:
        _REFINEMENTS[key] = ref
        _REFINEMENTS.move_to_end(key)
        while len(_REFINEMENTS) > 1 and sum(_refinement_bytes(r) for r in _REFINEMENTS.values() if r is not None) \
                > REFINEMENT_CACHE_BYTES:
            _REFINEMENTS.popitem(last=False)


#: refinements kept across frames (a stage's topology rarely changes from frame to frame; the
#: Teapot's two levels took 0.3 s of its 0.4 s frame to build)
REFINEMENT_CACHE_BYTES = 512 * 2**20
_REFINEMENTS: OrderedDict = OrderedDict()
_REFINEMENTS_LOCK = threading.Lock()


def mesh_refinement(mesh, time, num_points: int, levels: int):
    """(Refinement, counts, indices) for a catmullClark or loop UsdGeom.Mesh that can be refined
    here, else None (bilinear, holes, non-manifold topology, a loop mesh with faces other than
    triangles: its cage renders with smooth normals). Refinements are kept by topology
    (_refinement_key), so the frames of a range build each one once."""
    from pxr import UsdGeom

    from ..core.log import warn_once
    scheme = mesh.GetSubdivisionSchemeAttr().Get(time)
    if levels < 1 or scheme not in (UsdGeom.Tokens.catmullClark, UsdGeom.Tokens.loop):
        return None
    if value_count(mesh.GetHoleIndicesAttr(), time):
        return None
    counts = array_value(mesh.GetFaceVertexCountsAttr(), time, np.int64)
    indices = array_value(mesh.GetFaceVertexIndicesAttr(), time, np.int64)
    if mesh.GetOrientationAttr().Get(time) == UsdGeom.Tokens.leftHanded:
        return None
    creases, corners = crease_tables(mesh, time, num_points)
    if scheme == UsdGeom.Tokens.loop and (creases or corners.any()):
        warn_once(f"loopcrease:{mesh.GetPath()}", f"{mesh.GetPath()}: creases and corners of a loop mesh are "
                                                  f"not read (smooth Loop rules)")
    key = _refinement_key(scheme, counts, indices, num_points, levels, creases, corners)
    with _REFINEMENTS_LOCK:
        known = key in _REFINEMENTS
        ref = _REFINEMENTS.get(key)
    if not known:
        if scheme == UsdGeom.Tokens.loop:
            out = loop_refine(counts, indices, num_points, levels)
            ref = None if out is None else Refinement(out[0], out[1], out[2], out[3], levels)
        else:
            ref = refine(counts, indices, num_points, levels, creases, corners)
        _remember(key, ref)
    return None if ref is None else (ref, counts, indices)


def refined_surface_primvars(prim, time, reads, counts: np.ndarray, indices: np.ndarray, parent: np.ndarray,
                             weights: np.ndarray):
    """(corner colours (T', 3, 3) or None, corner texture coordinates (T', 3, 2) or None, corner
    opacities (T', 3) or None) that a material reading `reads` (materials.MaterialReads) needs,
    on the refined triangles."""
    colors = refined_corner_primvar(prim, reads.color, time, counts, indices, parent, weights, 3) if reads.color else None
    uvs = None
    if reads.st:
        uvs = refined_corner_primvar(prim, reads.st, time, counts, indices, parent, weights, 2)
        if uvs is None:
            uvs = np.zeros((len(parent), 3, 2), np.float32)
    opacity = None
    if reads.opacity:
        values = refined_corner_primvar(prim, reads.opacity, time, counts, indices, parent, weights, 1)
        opacity = None if values is None else np.clip(values[..., 0], 0.0, 1.0)
    return colors, uvs, opacity
