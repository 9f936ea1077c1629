"""Reading the light table over the shutter in kernels (@wp.func only): columns are documented in
lights.py; tables are stored at knots over the shutter and read linearly between them."""

from __future__ import annotations

import warp as wp

from .kernel_types import Shading


@wp.func
def light_value(sh: Shading, j: int, col: int, u: float) -> float:
    """Column `col` of light j at shutter time u (linear between the light knots)."""
    if sh.light_segments == 0:
        return sh.lights[0, j, col]
    x = wp.clamp(u, 0.0, 1.0) * float(sh.light_segments)
    k = wp.min(int(x), sh.light_segments - 1)
    f = x - float(k)
    return sh.lights[k, j, col] * (1.0 - f) + sh.lights[k + 1, j, col] * f


@wp.func
def light_vec(sh: Shading, j: int, col: int, u: float) -> wp.vec3:
    return wp.vec3(light_value(sh, j, col, u), light_value(sh, j, col + 1, u), light_value(sh, j, col + 2, u))
