"""NumPy arrays handed to host-side Warp kernels (the float64 set-up passes over vertices and
entries): the same memory on the CPU wherever the dtype and layout already match, a copy otherwise
(and on another device)."""

from __future__ import annotations

import numpy as np
import warp as wp

from . import warp_setup  # noqa: F401  (Warp's settings, before anything starts it)


def vec3d_array(points: np.ndarray, device: str = "cpu") -> wp.array:
    """points (..., N, 3) as float64 wp.vec3d (..., N)."""
    return wp.array(np.ascontiguousarray(points, np.float64), dtype=wp.vec3d, device=device, copy=False)


def vec3i_array(triangles: np.ndarray, device: str = "cpu") -> wp.array:
    """triangles (T, 3) vertex indices as wp.vec3i (T,)."""
    return wp.array(np.ascontiguousarray(triangles, np.int32), dtype=wp.vec3i, device=device, copy=False)


def int32_array(values: np.ndarray, device: str = "cpu") -> wp.array:
    """values (N,) as int32 (N,)."""
    return wp.array(np.ascontiguousarray(values, np.int32), dtype=wp.int32, device=device, copy=False)
