"""Catmull-Clark refinement of subdivision meshes (USD's default scheme) instead of their control
cage: each level is a sparse stencil S (refined points = S @ cage points), built once per frame,
so a deforming or moving cage is refined at every shutter time by one matrix product.

Rules: face points are face centroids; interior edge points average the edge's ends and its two
faces' points; interior vertices move to (Q + 2R + (n − 3) P) / n; boundary edges and vertices
follow the boundary curve (3/4 P + 1/8 of each boundary neighbour), and a boundary vertex with two
edges is a corner that stays put (USD's `edgeAndCorner`). Meshes with authored creases or corners,
holes, a left-handed orientation or non-manifold edges are not refined (their cage is rendered,
as before), nor are point-instancer prototypes and skinned meshes. The level is one for the
stage: the highest (up to MAX_LEVEL) at which all its subdivision meshes together stay within
SCENE_FACE_BUDGET faces (a triangle budget, not the meshes' size on screen). Primvars are
carried per face corner, bilinearly within each cage face.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import sparse

#: refine while every subdivision mesh of the stage together stays under this many faces (and at
#: most MAX_LEVEL levels): one level for the whole stage, so that its meshes look alike
SCENE_FACE_BUDGET = 100_000
MAX_LEVEL = 2


@dataclass(frozen=True)
class Refinement:
    """stencil: (N', N) sparse cage -> refined points; quads: (F', 4) refined vertex indices;
    parent_face: (F',) cage face of each quad; corner_of: (F', 4, K) weights of each quad
    corner over its cage face's corners (K = the most corners of a cage face, zero-padded)."""

    stencil: sparse.csr_matrix
    quads: np.ndarray
    parent_face: np.ndarray
    corner_weights: np.ndarray
    levels: int


def _one_level(faces: list[np.ndarray], n: int):
    """One Catmull-Clark level of polygons `faces` over n points: (stencil (n', n), quads (F', 4),
    (face, corner) of each quad's source and per-corner weights over the face's corners), or None
    for a non-manifold mesh."""
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
    # face points
    rows = np.concatenate([np.full(len(fv), f) for f, fv in enumerate(faces)])
    cols = np.concatenate(faces)
    vals = np.concatenate([np.full(len(fv), 1.0 / len(fv)) for fv in faces])
    face_pts = sparse.csr_matrix((vals, (rows, cols)), shape=(nf, n))
    # edge points
    boundary = np.array([len(ef) == 1 for ef in edge_faces])
    mid = sparse.csr_matrix((np.full(2 * ne, 0.5), (np.repeat(np.arange(ne), 2), edges.ravel())), shape=(ne, n))
    ef_rows = [e for e, ef in enumerate(edge_faces) if len(ef) == 2 for _ in ef]
    ef_cols = [f for ef in edge_faces if len(ef) == 2 for f in ef]
    edge_face_avg = sparse.csr_matrix((np.full(len(ef_rows), 0.5), (ef_rows, ef_cols)), shape=(ne, nf))
    interior_e = sparse.diags((~boundary).astype(float))
    edge_pts = sparse.diags(np.where(boundary, 1.0, 0.5)) @ mid + 0.5 * interior_e @ (edge_face_avg @ face_pts)
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
    for v in range(n):
        es = v_edges[v]
        if not es:                      # a point no face uses: keep it
            vr.append(v), vc.append(v), vv.append(1.0)
            continue
        bnd = [e for e in es if boundary[e]]
        if bnd:
            if len(es) == 2 and len(bnd) == 2:      # a corner
                vr.append(v), vc.append(v), vv.append(1.0)
            else:
                vr.append(v), vc.append(v), vv.append(0.75)
                for e in bnd[:2]:
                    other = edges[e][0] if edges[e][1] == v else edges[e][1]
                    vr.append(v), vc.append(int(other)), vv.append(0.125)
            continue
        k = len(es)
        for f in v_faces[v]:           # Q / k: the mean of the faces' points, over k
            fr.append(v), fc.append(f), fw.append(1.0 / (len(v_faces[v]) * k))
        for e in es:                    # 2 R / k: edge midpoints' mean
            for w in edges[e]:
                vr.append(v), vc.append(int(w)), vv.append(2.0 * 0.5 / (k * k))
        vr.append(v), vc.append(v), vv.append((k - 3.0) / k)
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
    return stencil, np.asarray(quads, np.int64), sources


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
            if mesh.GetSubdivisionSchemeAttr().Get(time) == UsdGeom.Tokens.catmullClark:
                counts = mesh.GetFaceVertexCountsAttr().Get(time)
                faces += int(np.sum(counts)) if counts is not None else 0   # refined faces: one per corner
    level = 0
    while level < MAX_LEVEL and faces * 4 ** level <= SCENE_FACE_BUDGET:
        level += 1
    return level


def refine(counts: np.ndarray, indices: np.ndarray, num_points: int, levels: int) -> Refinement | None:
    """`levels` Catmull-Clark levels of a cage (faceVertexCounts, faceVertexIndices over
    num_points); None when the mesh cannot be refined here (non-manifold, degenerate faces) or
    levels is 0."""
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
        out = _one_level(faces, n)
        if out is None:
            return None
        s, quads, sources = out
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
    return Refinement(stencil, quads, parent, weights, level)


def refined_triangles(ref: Refinement) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(tris (2F', 3) int32, parent cage face (2F',), corner weights (2F', 3, K)) of the refined
    quads split along their 0-2 diagonal."""
    q = ref.quads
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


def mesh_refinement(mesh, time, num_points: int, levels: int):
    """(Refinement, counts, indices) for a catmullClark UsdGeom.Mesh that can be refined here, else
    None (other schemes, holes, creases or corners, non-manifold topology: its cage renders with
    smooth normals; creases and corners with a warning)."""
    from pxr import UsdGeom

    from ..core.log import warn_once
    if levels < 1 or mesh.GetSubdivisionSchemeAttr().Get(time) != UsdGeom.Tokens.catmullClark:
        return None
    if len(mesh.GetHoleIndicesAttr().Get(time) or []):
        return None
    counts = np.asarray(mesh.GetFaceVertexCountsAttr().Get(time) or [], np.int64)
    indices = np.asarray(mesh.GetFaceVertexIndicesAttr().Get(time) or [], np.int64)
    if mesh.GetOrientationAttr().Get(time) == UsdGeom.Tokens.leftHanded:
        return None
    if len(mesh.GetCreaseIndicesAttr().Get(time) or []) or len(mesh.GetCornerIndicesAttr().Get(time) or []):
        warn_once(f"creases:{mesh.GetPath()}", f"{mesh.GetPath()}: subdivision creases and corners are not "
                                              f"refined; its control cage is rendered")
        return None
    ref = refine(counts, indices, num_points, levels)
    return None if ref is None else (ref, counts, indices)


def refined_surface_primvars(prim, time, reads, counts: np.ndarray, indices: np.ndarray, parent: np.ndarray,
                             weights: np.ndarray) -> tuple[np.ndarray | None, np.ndarray | None]:
    """(corner colours (T', 3, 3) or None, corner texture coordinates (T', 3, 2) or None) that a
    material reading `reads` (materials.MaterialReads) needs, on the refined triangles."""
    colors = refined_corner_primvar(prim, reads.color, time, counts, indices, parent, weights, 3) if reads.color else None
    uvs = None
    if reads.st:
        uvs = refined_corner_primvar(prim, reads.st, time, counts, indices, parent, weights, 2)
        if uvs is None:
            uvs = np.zeros((len(parent), 3, 2), np.float32)
    return colors, uvs
