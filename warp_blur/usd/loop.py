"""Loop refinement of `subdivisionScheme = "loop"` triangle meshes (USD's scheme for triangles), as
sparse stencils like subdivision.py's Catmull-Clark: each triangle splits into four per level.

Rules (Loop 1987, OpenSubdiv's smooth rules; creases are not read for Loop): an interior edge
point is 3/8 of its ends and 1/8 of the two opposite vertices, a boundary edge's is its midpoint;
an interior vertex of valence n moves to (1 − nβ) P + β Σ neighbours with β = (5/8 − (3/8 +
cos(2π/n)/4)²) / n; a boundary vertex follows its boundary curve (3/4 P + 1/8 of each boundary
neighbour), and one with only two edges is a corner that stays put (USD's `edgeAndCorner`).
Meshes with faces other than triangles or with non-manifold edges are not refined (None).
"""

from __future__ import annotations

import numpy as np


def _one_level(tris: np.ndarray, n: int):
    """(stencil (n + E, n), child triangles (4F, 3), (face, child) of each) of one Loop level over
    n points, or None for a non-manifold mesh."""
    from scipy import sparse   # (imported where used: ~0.13 s at start-up, for stages that subdivide)
    f = len(tris)
    e_all = np.stack([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]], axis=1).reshape(-1, 2)   # (3F, 2)
    opposite = tris[:, [2, 0, 1]].reshape(-1)                                                      # (3F,)
    key = np.minimum(e_all[:, 0], e_all[:, 1]) * np.int64(n) + np.maximum(e_all[:, 0], e_all[:, 1])
    uniq, edge_of, count = np.unique(key, return_inverse=True, return_counts=True)
    if (count > 2).any():
        return None
    ne = len(uniq)
    ends = np.stack([uniq // n, uniq % n], axis=1)
    boundary = count == 1
    # edge points
    rows, cols, vals = [], [], []
    e_idx = np.arange(ne)
    for k in range(2):
        rows.append(e_idx)
        cols.append(ends[:, k])
        vals.append(np.where(boundary, 0.5, 0.375))
    rows.append(edge_of)
    cols.append(opposite)
    vals.append(np.where(boundary[edge_of], 0.0, 0.125))
    edge_pts = sparse.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(ne, n))
    # vertex points
    nbr = sparse.csr_matrix((np.ones(2 * ne), (ends.ravel(), ends[:, ::-1].ravel())), shape=(n, n))
    valence = np.asarray(nbr.sum(axis=1)).ravel()
    bnd_nbr = sparse.csr_matrix((np.ones(2 * int(boundary.sum())), (ends[boundary].ravel(),
                                                                     ends[boundary][:, ::-1].ravel())), shape=(n, n))
    on_boundary = np.asarray(bnd_nbr.sum(axis=1)).ravel() > 0
    with np.errstate(divide="ignore", invalid="ignore"):
        beta = np.where(valence > 0, (0.625 - (0.375 + 0.25 * np.cos(2 * np.pi / np.maximum(valence, 1))) ** 2)
                        / np.maximum(valence, 1), 0.0)
    corner = on_boundary & (valence == 2)
    self_w = np.where(on_boundary, np.where(corner, 1.0, 0.75), 1.0 - valence * beta)
    nbr_w = sparse.diags(np.where(on_boundary, 0.0, beta)) @ nbr + sparse.diags(
        np.where(on_boundary & ~corner, 0.125, 0.0)) @ bnd_nbr
    vert_pts = sparse.diags(self_w) + nbr_w
    stencil = sparse.vstack([vert_pts, edge_pts]).tocsr()
    ep = n + edge_of.reshape(f, 3)              # edge points of (a b), (b c), (c a)
    a, b, c = tris[:, 0], tris[:, 1], tris[:, 2]
    children = np.stack([np.stack([a, ep[:, 0], ep[:, 2]], 1), np.stack([ep[:, 0], b, ep[:, 1]], 1),
                         np.stack([ep[:, 2], ep[:, 1], c], 1), np.stack([ep[:, 0], ep[:, 1], ep[:, 2]], 1)], axis=1)
    return stencil, children.reshape(-1, 3).astype(np.int64)


#: (4, 3, 3): weights over a triangle's corners of each child's corners (the order _one_level makes)
_CHILD_WEIGHTS = np.array([
    [[1, 0, 0], [0.5, 0.5, 0], [0.5, 0, 0.5]],
    [[0.5, 0.5, 0], [0, 1, 0], [0, 0.5, 0.5]],
    [[0.5, 0, 0.5], [0, 0.5, 0.5], [0, 0, 1]],
    [[0.5, 0.5, 0], [0, 0.5, 0.5], [0.5, 0, 0.5]]], np.float64)


def loop_refine(counts: np.ndarray, indices: np.ndarray, num_points: int, levels: int):
    """(stencil (N', N), triangles (F', 3), parent face (F',), corner weights (F', 3, 3)) after
    `levels` Loop levels of a triangle cage, or None (a face that is not a triangle, non-manifold
    edges, or levels < 1)."""
    from scipy import sparse   # (imported where used: ~0.13 s at start-up, for stages that subdivide)
    if levels < 1 or len(counts) == 0 or (counts != 3).any():
        return None
    tris = indices.reshape(-1, 3).astype(np.int64)
    stencil = sparse.identity(num_points, format="csr")
    parent = np.arange(len(tris))
    weights = np.repeat(np.eye(3)[None], len(tris), axis=0)
    n = num_points
    for _level in range(levels):
        out = _one_level(tris, n)
        if out is None:
            return None
        s, tris = out
        stencil = (s @ stencil).tocsr()
        n = stencil.shape[0]
        weights = np.einsum("cij,fjk->fcik", _CHILD_WEIGHTS, weights).reshape(-1, 3, 3)
        parent = np.repeat(parent, 4)
    return stencil, tris, parent, weights
