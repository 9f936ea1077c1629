"""An entry's triangle at both ends of its motion span (camera space), and the view depth where a
pixel ray meets it at an entry time s in [0, 1] (vertices move linearly in s)."""

from __future__ import annotations

import warp as wp

from ...kernels.kernel_types import Geometry, View
from ...kernels.rays import hit_from_edges, pixel_ray_direction, pixel_ray_origin


@wp.struct
class Moving:
    """An entry's triangle at both ends of its span (camera space)."""

    a0: wp.vec3
    b0: wp.vec3
    c0: wp.vec3
    a1: wp.vec3
    b1: wp.vec3
    c1: wp.vec3
    u0: float
    u1: float


@wp.func
def entry_moving(geo: Geometry, e: int) -> Moving:
    """Entry e's triangle at both ends of its span (a static entry spans the whole shutter): from
    the frame's corner table where it has one (one contiguous row), else gathered from positions."""
    k0 = geo.entry_k0[e]
    k1 = geo.entry_k1[e]
    m = Moving()
    if geo.entry_corners.shape[1] == 6:
        m.a0 = geo.entry_corners[e, 0]
        m.b0 = geo.entry_corners[e, 1]
        m.c0 = geo.entry_corners[e, 2]
        m.a1 = geo.entry_corners[e, 3]
        m.b1 = geo.entry_corners[e, 4]
        m.c1 = geo.entry_corners[e, 5]
    else:
        vi = geo.tri_vertices[geo.entry_tri[e]]
        m.a0 = geo.positions[k0, vi[0]]
        m.b0 = geo.positions[k0, vi[1]]
        m.c0 = geo.positions[k0, vi[2]]
        m.a1 = geo.positions[k1, vi[0]]
        m.b1 = geo.positions[k1, vi[1]]
        m.c1 = geo.positions[k1, vi[2]]
    m.u0 = 0.0
    m.u1 = 1.0
    if k0 != k1:
        m.u0 = float(k0) / float(geo.num_segments)
        m.u1 = float(k1) / float(geo.num_segments)
    return m


@wp.kernel(enable_backward=False)
def corner_table(positions: wp.array2d(dtype=wp.vec3), tri_vertices: wp.array(dtype=wp.vec3i),
                 entry_tri: wp.array(dtype=int), entry_k0: wp.array(dtype=int), entry_k1: wp.array(dtype=int),
                 # output
                 table: wp.array2d(dtype=wp.vec3)):
    """table[e] = entry e's vertices a, b, c at snapshot k0, then at k1 (camera space): what
    entry_moving gathers from positions through two indirections, in one 72-byte row, for the
    passes that read every listed entry at every pixel."""
    e = wp.tid()
    vi = tri_vertices[entry_tri[e]]
    for j in range(3):
        table[e, j] = positions[entry_k0[e], vi[j]]
        table[e, 3 + j] = positions[entry_k1[e], vi[j]]


@wp.func
def entry_time(m: Moving, u: float) -> float:
    """Entry time s of shutter time u (0 at the span's start, 1 at its end)."""
    if m.u1 <= m.u0:
        return 0.0
    return (u - m.u0) / (m.u1 - m.u0)


@wp.func
def plane_depth(o: wp.vec3, d: wp.vec3, a: wp.vec3, b: wp.vec3, c: wp.vec3) -> float:
    """View depth where the ray meets the triangle's plane (inf when parallel)."""
    n = wp.cross(b - a, c - a)
    den = wp.dot(d, n)
    if den == 0.0:
        return wp.inf
    return wp.dot(a - o, n) / den


@wp.func
def plane_hit(o: wp.vec3, d: wp.vec3, a: wp.vec3, b: wp.vec3, c: wp.vec3) -> wp.vec4:
    """(1, depth, w_b, w_c) of the ray and the triangle's plane, without the inside test."""
    ao = a - o
    bo = b - o
    co = c - o
    return hit_from_edges(a, b, c, wp.dot(d, wp.cross(ao, bo)), wp.dot(d, wp.cross(bo, co)), wp.dot(d, wp.cross(co, ao)))


@wp.func
def depth_at(m: Moving, o: wp.vec3, d: wp.vec3, s: float) -> float:
    return plane_depth(o, d, m.a0 + s * (m.a1 - m.a0), m.b0 + s * (m.b1 - m.b0), m.c0 + s * (m.c1 - m.c0))


@wp.func
def depth_polynomials(m: Moving, o: wp.vec3, d: wp.vec3):
    """(N, D): coefficients of 1, s, s², s³ of plane_depth's numerator N(s) = (a(s) - o) · n(s)
    (a cubic) and denominator D(s) = d · n(s) (a quadratic; its 4th is 0), n(s) = (b - a) × (c - a)
    quadratic in the entry time s, so that depth_at(m, o, d, s) = N(s) / D(s). Evaluating them
    costs a fifth of depth_at: for the near/far crossings' many samples."""
    a0 = m.a0 - o
    da = m.a1 - m.a0
    e1 = m.b0 - m.a0
    de1 = (m.b1 - m.b0) - da
    e2 = m.c0 - m.a0
    de2 = (m.c1 - m.c0) - da
    n0 = wp.cross(e1, e2)
    n1 = wp.cross(e1, de2) + wp.cross(de1, e2)
    n2 = wp.cross(de1, de2)
    num = wp.vec4(wp.dot(a0, n0), wp.dot(a0, n1) + wp.dot(da, n0), wp.dot(a0, n2) + wp.dot(da, n1), wp.dot(da, n2))
    den = wp.vec4(wp.dot(d, n0), wp.dot(d, n1), wp.dot(d, n2), 0.0)
    return num, den


@wp.func
def in_range_at(view: View, num: wp.vec4, den: wp.vec4, s: float) -> bool:
    """in_range of the depth N(s) / D(s) (depth_polynomials), without the division: a plane
    parallel to the ray (D = 0) is out of range, as plane_depth's inf is."""
    n = num[0] + s * (num[1] + s * (num[2] + s * num[3]))
    dn = den[0] + s * (den[1] + s * den[2])
    if dn > 0.0:
        return n >= view.near * dn and n <= view.far * dn
    if dn < 0.0:
        return n <= view.near * dn and n >= view.far * dn
    return False


@wp.func
def depth_range(m: Moving) -> wp.vec2:
    """(nearest, farthest) view depth of the triangle's six vertices: its hits over the span are
    convex combinations of them."""
    zmin = wp.min(wp.min(wp.min(-m.a0[2], -m.b0[2]), wp.min(-m.c0[2], -m.a1[2])), wp.min(-m.b1[2], -m.c1[2]))
    zmax = wp.max(wp.max(wp.max(-m.a0[2], -m.b0[2]), wp.max(-m.c0[2], -m.a1[2])), wp.max(-m.b1[2], -m.c1[2]))
    return wp.vec2(zmin, zmax)


@wp.func
def eye_relative(m: Moving, o: wp.vec3):
    """The triangle's vertices at the span's start relative to the ray origin, and their changes."""
    return m.a0 - o, m.b0 - o, m.c0 - o, m.a1 - m.a0, m.b1 - m.b0, m.c1 - m.c0


@wp.func
def in_range(view: View, z: float) -> bool:
    return z >= view.near and z <= view.far


@wp.func
def sample_ray(view: View, px: int, py: int, sub: wp.vec2):
    """(origin, direction) of the ray through sub-pixel position sub of pixel (px, py)."""
    x = float(px) + sub[0]
    y = float(py) + sub[1]
    return pixel_ray_origin(view, x, y), pixel_ray_direction(view, x, y)
