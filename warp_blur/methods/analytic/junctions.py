"""Junctions: where an interval the bitmask resolve shades meets one it has shaded already, at
the same point at the same time (a motion-segment junction of one triangle, a piece of one entry's
cut span, or the edge two smooth neighbours of a mesh share), so that end takes the radiance
shaded there instead of shading the same point again (resolve.resolve_bitmask).
"""

from __future__ import annotations

import warp as wp

from ...kernels.kernel_types import Geometry, Shading


@wp.func
def smooth_neighbours(geo: Geometry, sh: Shading, a: int, b: int) -> int:
    """1 when triangles a and b shade a point on their common edge alike: they share an edge (two
    vertex indices, wound consistently), both interpolate vertex normals, and have the same
    untextured material without a normal map, with equal corner colours at the shared vertices."""
    if (geo.tri_flags[a] & 2) == 0 or (geo.tri_flags[b] & 2) == 0:
        return 0
    m = geo.tri_material[a]
    if geo.tri_material[b] != m or sh.materials[m, 21] > 0.5 or sh.materials[m, 22] >= 0.0:
        return 0
    va = geo.tri_vertices[a]
    vb = geo.tri_vertices[b]
    shared = int(0)
    wound = int(0)
    for i in range(3):
        for j in range(3):
            if va[i] == vb[j]:
                shared += 1
                ca = geo.tri_colors[3 * a + i]
                cb = geo.tri_colors[3 * b + j]
                if ca[0] != cb[0] or ca[1] != cb[1] or ca[2] != cb[2]:
                    return 0
                # a's edge i -> i + 1 runs backwards in b (j + 1 -> j): consistent winding
                if va[(i + 1) % 3] == vb[(j + 2) % 3]:
                    wound = 1
    if shared == 2 and wound == 1:
        return 1
    return 0


@wp.func
def junction(geo: Geometry, sh: Shading, e: int, t: wp.vec2, other: int, other_t: wp.vec2, kinds: int) -> int:
    """1 when the interval (entry e, shutter span t) starts where interval `other` (span other_t)
    ends, 2 when it ends where `other` starts, at the same point at the same time: (kinds bit 0)
    a motion-segment junction of one triangle (the two entries are consecutive segments of it),
    or (bit 1) the edge two smooth neighbours of one mesh share (entries of the same span; the
    edge quadratics are exactly antisymmetric, so the ray crosses it at the same time in both),
    or where one entry's span was cut in pieces. Else 0."""
    if other < 0:
        return 0
    k0 = geo.entry_k0[e]
    k1 = geo.entry_k1[e]
    if k0 == k1:
        return 0
    same_span = geo.entry_k0[other] == k0 and geo.entry_k1[other] == k1
    if geo.entry_tri[other] == geo.entry_tri[e]:
        if (kinds & 1) != 0:
            if (geo.entry_k1[other] == k0 or same_span) and t[0] == other_t[1]:
                return 1
            if (geo.entry_k0[other] == k1 or same_span) and t[1] == other_t[0]:
                return 2
        return 0
    if (kinds & 2) != 0 and same_span and (t[0] == other_t[1] or t[1] == other_t[0]):
        if smooth_neighbours(geo, sh, geo.entry_tri[e], geo.entry_tri[other]) != 0:
            if t[0] == other_t[1]:
                return 1
            return 2
    return 0


@wp.func
def take_junction(geo: Geometry, sh: Shading, e: int, t: wp.vec2, other: int, other_t: wp.vec2, other_a: wp.vec3,
                  other_b: wp.vec3, known: int, known_a: wp.vec3, known_b: wp.vec3, kinds: int):
    """(known, known_a, known_b) with the end of the interval (entry e, span t) that interval
    `other` (span other_t, radiance other_a at its start, other_b at its end) meets at a junction
    taken from it, when that end is not known yet."""
    j = junction(geo, sh, e, t, other, other_t, kinds)
    if j == 1 and (known & 1) == 0:
        return known | 1, other_b, known_b
    if j == 2 and (known & 2) == 0:
        return known | 2, known_a, other_a
    return known, known_a, known_b
