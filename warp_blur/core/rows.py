"""Row tests over (N, 3) arrays and triangles' corners, column by column.

NumPy's reductions over a short last axis (`.all(axis=1)` of an (N, 3) array, or of a per-vertex
mask gathered at each triangle's corners) run ~3x slower than three column operations; over a
million triangles these tests ran several times a frame (accumulation: at every instant).
Results are the same booleans.
"""

from __future__ import annotations

import numpy as np


def same_rows(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(N,) bool: rows of a and b (N, 3) equal in every column, (a == b).all(axis=1)."""
    return (a[:, 0] == b[:, 0]) & (a[:, 1] == b[:, 1]) & (a[:, 2] == b[:, 2])


def all_corners(mask: np.ndarray, tri_vertices: np.ndarray) -> np.ndarray:
    """(T,) bool: triangles (T, 3) vertex indices whose three corners all hold in the per-vertex
    mask (V,), mask[tri_vertices].all(axis=1)."""
    if len(tri_vertices) == 0:
        return np.zeros(0, bool)
    return mask[tri_vertices[:, 0]] & mask[tri_vertices[:, 1]] & mask[tri_vertices[:, 2]]


def any_corner(mask: np.ndarray, tri_vertices: np.ndarray) -> np.ndarray:
    """(T,) bool: triangles with some corner in the per-vertex mask (V,), mask[tri_vertices].any(axis=1)."""
    if len(tri_vertices) == 0:
        return np.zeros(0, bool)
    return mask[tri_vertices[:, 0]] | mask[tri_vertices[:, 1]] | mask[tri_vertices[:, 2]]
