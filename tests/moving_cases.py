"""Random moving triangles and rays through them, shared by the kernel tests of
methods/analytic/moving.py and occlusion.py."""

import numpy as np
import warp as wp

from warp_blur.methods.analytic.moving import Moving


@wp.func
def case_triangle(p0: wp.array2d(dtype=wp.vec3), p1: wp.array2d(dtype=wp.vec3), i: int) -> Moving:
    """Case i's triangle: p0[i] at the span's start moving to p1[i] at its end (a whole-shutter span)."""
    m = Moving()
    m.a0 = p0[i, 0]
    m.b0 = p0[i, 1]
    m.c0 = p0[i, 2]
    m.a1 = p1[i, 0]
    m.b1 = p1[i, 1]
    m.c1 = p1[i, 2]
    m.u0 = 0.0
    m.u1 = 1.0
    return m


def random_moving_cases(rng: np.random.Generator, n: int, depth: float, move: float, degenerate: bool = False):
    """(p0, p1, times, origins, dirs): n triangles around `depth` in front of the eye, moving by
    ~`move` and turning; degenerate: the third vertex within 1e-4 of the line through the other
    two at both ends. Each ray goes from the eye (half of them from points off it, as
    orthographic rays start) through a random point of its triangle at entry time times[i]; its
    direction has unit depth."""
    p0 = rng.uniform(-3, 3, (n, 3, 3)) + np.array([0.0, 0.0, -depth])
    p1 = p0 + rng.normal(0, move, (n, 1, 3)) + rng.normal(0, 0.8, (n, 3, 3))   # moves and turns
    if degenerate:
        t = rng.uniform(0, 1, (n, 1))
        p0[:, 2] = p0[:, 0] + t * (p0[:, 1] - p0[:, 0]) + rng.normal(0, 1e-4, (n, 3))
        p1[:, 2] = p1[:, 0] + t * (p1[:, 1] - p1[:, 0]) + rng.normal(0, 1e-4, (n, 3))
    times = rng.uniform(0, 1, n)
    origins = np.zeros((n, 3))
    origins[n // 2:, :2] = rng.uniform(-1, 1, (n - n // 2, 2))
    w = rng.dirichlet((1, 1, 1), n)
    target = np.einsum("nk,nkj->nj", w, p0 + times[:, None, None] * (p1 - p0))
    dirs = target - origins
    return p0, p1, times, origins, dirs / -dirs[:, 2:3]
