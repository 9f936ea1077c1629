"""Pixel rays and the watertight ray-triangle test shared by every method (@wp.func only).

Edge functions are triple products e_ab = d · ((a-o) × (b-o)): the ray passes on the same side of
all three edges when it hits the triangle, whatever its orientation (back faces are never culled).
A shared edge gives exactly opposite values in its two triangles, and a sample exactly on it is
owned by one of them (`edge_owns`), so meshes are watertight, pixel centres on edges included.
The same formulas handle vertices behind the eye: the hit point's view depth is tested against
the near and far planes per sample, so triangles crossing the near plane are clipped exactly.
"""

from __future__ import annotations

from typing import Any

import warp as wp

from .kernel_types import Geometry, View


@wp.func
def pixel_ray_origin(view: View, x: float, y: float) -> wp.vec3:
    """Camera-space ray origin for a raster position (x, y in pixels, y down)."""
    wx = view.win_min[0] + (x / float(view.width)) * (view.win_max[0] - view.win_min[0])
    wy = view.win_max[1] - (y / float(view.height)) * (view.win_max[1] - view.win_min[1])
    if view.ortho != 0:
        return wp.vec3(wx, wy, 0.0)
    return wp.vec3(0.0, 0.0, 0.0)


@wp.func
def pixel_ray_direction(view: View, x: float, y: float) -> wp.vec3:
    """Camera-space ray direction (not unit: its z is -1, so the ray parameter is view depth)."""
    wx = view.win_min[0] + (x / float(view.width)) * (view.win_max[0] - view.win_min[0])
    wy = view.win_max[1] - (y / float(view.height)) * (view.win_max[1] - view.win_min[1])
    if view.ortho != 0:
        return wp.vec3(0.0, 0.0, -1.0)
    return wp.vec3(wx, wy, -1.0)


@wp.func
def edge_owns(c: Any) -> bool:
    """Tie rule for a sample exactly on an edge: exactly one of c and -c owns it (generic over
    float32/float64 vectors, as the analytic coverage functions are)."""
    zero = type(c[0])(0.0)
    if c[0] != zero:
        return c[0] > zero
    if c[1] != zero:
        return c[1] > zero
    return c[2] > zero


@wp.func
def edge_cross(a: Any, b: Any, ia: int, ib: int):
    """a × b for an edge from vertex ia to ib (eye-relative positions), computed from the
    lower-index vertex as base × (other − base): exactly antisymmetric between the two triangles
    sharing the edge, and with rounding that scales with the edge's length rather than with the
    distance to the eye (small, distant triangles stay accurate in float32)."""
    if ia < ib:
        return wp.cross(a, b - a)
    return -wp.cross(b, a - b)


@wp.func
def hit_from_edges(a: wp.vec3, b: wp.vec3, c: wp.vec3, e_ab: float, e_bc: float, e_ca: float) -> wp.vec4:
    """(1, view depth, barycentric of b, barycentric of c) of the point on abc's plane that the
    edge functions locate ((0, ...) when they sum to zero: the ray is parallel to the plane)."""
    s = e_ab + e_bc + e_ca
    if s == 0.0:
        return wp.vec4(0.0, 0.0, 0.0, 0.0)
    wb = e_ca / s
    wc = e_ab / s
    p = (e_bc / s) * a + wb * b + wc * c
    return wp.vec4(1.0, -p[2], wb, wc)


@wp.func
def hit_through_edges(d: wp.vec3, a: wp.vec3, b: wp.vec3, c: wp.vec3, c_ab: wp.vec3, c_bc: wp.vec3,
                      c_ca: wp.vec3) -> wp.vec4:
    """intersect_triangle's test for direction d, given the edges' cross products (edge_cross of
    the origin-relative vertices): a perspective face, whose rays share one origin, computes them
    once per triangle instead of once per texel."""
    e_ab = wp.dot(d, c_ab)
    e_bc = wp.dot(d, c_bc)
    e_ca = wp.dot(d, c_ca)
    if e_ab + e_bc + e_ca == 0.0:
        return wp.vec4(0.0, 0.0, 0.0, 0.0)
    pos = (e_ab > 0.0 or (e_ab == 0.0 and edge_owns(c_ab))) and (e_bc > 0.0 or (e_bc == 0.0 and edge_owns(c_bc))) and (e_ca > 0.0 or (e_ca == 0.0 and edge_owns(c_ca)))
    neg = (e_ab < 0.0 or (e_ab == 0.0 and edge_owns(-c_ab))) and (e_bc < 0.0 or (e_bc == 0.0 and edge_owns(-c_bc))) and (e_ca < 0.0 or (e_ca == 0.0 and edge_owns(-c_ca)))
    if not (pos or neg):
        return wp.vec4(0.0, 0.0, 0.0, 0.0)
    return hit_from_edges(a, b, c, e_ab, e_bc, e_ca)


@wp.func
def intersect_triangle(o: wp.vec3, d: wp.vec3, a: wp.vec3, b: wp.vec3, c: wp.vec3, vi: wp.vec3i) -> wp.vec4:
    """(hit 0/1, view depth, barycentric of b, barycentric of c) of the line o + t d and abc,
    whose vertex indices are vi (they fix each shared edge's canonical orientation).

    The caller checks depth against the near/far planes (which also rejects hits behind the eye).
    """
    ao = a - o
    bo = b - o
    co = c - o
    return hit_through_edges(d, a, b, c, edge_cross(ao, bo, vi[0], vi[1]), edge_cross(bo, co, vi[1], vi[2]),
                             edge_cross(co, ao, vi[2], vi[0]))


@wp.func
def static_entry_hit(geo: Geometry, e: int, o: wp.vec3, d: wp.vec3) -> wp.vec4:
    """intersect_triangle for static entry e (its triangle at its one knot)."""
    vi = geo.tri_vertices[geo.entry_tri[e]]
    k = geo.entry_k0[e]
    return intersect_triangle(o, d, geo.positions[k, vi[0]], geo.positions[k, vi[1]], geo.positions[k, vi[2]], vi)


@wp.func
def entry_alpha(geo: Geometry, e: int, u: float) -> float:
    """Interpolation weight of knot k1 at shutter time u (-1 when u is outside the entry's span)."""
    k0 = geo.entry_k0[e]
    k1 = geo.entry_k1[e]
    if k0 == k1:
        return 0.0
    u0 = float(k0) / float(geo.num_segments)
    u1 = float(k1) / float(geo.num_segments)
    if u < u0 or u > u1:
        return -1.0
    return (u - u0) / (u1 - u0)


@wp.func
def entry_vertex(geo: Geometry, e: int, v: int, alpha: float) -> wp.vec3:
    """Camera-space position of vertex v of entry e at interpolation weight alpha."""
    p0 = geo.positions[geo.entry_k0[e], v]
    p1 = geo.positions[geo.entry_k1[e], v]
    return p0 + alpha * (p1 - p0)


@wp.func
def entry_normal(geo: Geometry, e: int, v: int, alpha: float) -> wp.vec3:
    n0 = geo.normals[geo.entry_k0[e], v]
    n1 = geo.normals[geo.entry_k1[e], v]
    return n0 + alpha * (n1 - n0)
