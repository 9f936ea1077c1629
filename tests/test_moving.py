"""The depth of a moving triangle along a ray as a ratio of polynomials (moving.depth_polynomials,
used for the near/far crossings) against plane_depth at the interpolated vertices (depth_at)."""

import numpy as np
import warp as wp

from warp_blur.kernels.kernel_types import View
from moving_cases import case_triangle, random_moving_cases
from warp_blur.methods.analytic.moving import depth_at, depth_polynomials, in_range, in_range_at


@wp.kernel(enable_backward=False)
def _depths(p0: wp.array2d(dtype=wp.vec3), p1: wp.array2d(dtype=wp.vec3), origins: wp.array(dtype=wp.vec3),
            dirs: wp.array(dtype=wp.vec3), times: wp.array(dtype=float), view: View,
            plane: wp.array(dtype=float), ratio: wp.array(dtype=float), in_plane: wp.array(dtype=int),
            in_ratio: wp.array(dtype=int)):
    """Case i: triangle p0[i] moving to p1[i], ray (origins[i], dirs[i]) at entry time times[i]:
    depth_at and N/D, and in_range by each."""
    i = wp.tid()
    m = case_triangle(p0, p1, i)
    o = origins[i]
    d = dirs[i]
    s = times[i]
    num, den = depth_polynomials(m, o, d)
    z = depth_at(m, o, d, s)
    plane[i] = z
    ratio[i] = (num[0] + s * (num[1] + s * (num[2] + s * num[3]))) / (den[0] + s * (den[1] + s * den[2]))
    in_plane[i] = int(in_range(view, z))
    in_ratio[i] = int(in_range_at(view, num, den, s))


def _run(p0, p1, origins, dirs, times, near, far):
    view = View()
    view.near = near
    view.far = far
    n = len(times)
    outs = [wp.zeros(n, dtype=float), wp.zeros(n, dtype=float), wp.zeros(n, dtype=int), wp.zeros(n, dtype=int)]
    wp.launch(_depths, dim=n, inputs=[wp.array(p0, dtype=wp.vec3), wp.array(p1, dtype=wp.vec3),
                                      wp.array(origins, dtype=wp.vec3), wp.array(dirs, dtype=wp.vec3),
                                      wp.array(times, dtype=float), view], outputs=outs, device="cpu")
    return [a.numpy() for a in outs]


def test_depth_polynomials_give_depth_at_and_its_range():
    """Random triangles moving towards, through and past the eye (perspective rays from it, and
    orthographic-style rays from points off it): N(s)/D(s) equals depth_at to float32 rounding,
    and in_range_at agrees with in_range(depth_at) wherever the depth is not within rounding of
    the near or far plane (the crossings the fill bisects)."""
    n = 4000
    # each ray through a random point of the triangle at a random time (covered cases, as the fill's)
    p0, p1, times, origins, dirs = random_moving_cases(np.random.default_rng(11), n, depth=4.0, move=3.0)
    ok = dirs[:, 2] < 0   # (all, by construction, unless the point is level with the eye)
    near, far = 1.0, 6.0
    plane, ratio, in_plane, in_ratio = _run(p0, p1, origins, np.where(ok[:, None], dirs, (0, 0, -1)), times, near,
                                            far)
    finite = np.isfinite(plane) & (np.abs(plane) < 1e3)
    assert finite.mean() > 0.95
    np.testing.assert_allclose(ratio[finite], plane[finite], rtol=2e-3, atol=1e-4)
    clear = finite & (np.abs(plane - near) > 1e-3) & (np.abs(plane - far) > 1e-3)
    assert (in_plane[clear] == in_ratio[clear]).all()
    # the cases cover all three sides: behind the near plane, in range and beyond the far one
    assert (plane[clear] < near).sum() > 100 and (in_plane[clear] == 1).sum() > 100 and (plane[clear] > far).sum() > 100
