"""Occlusion culling in the fill pass: intervals and whole entries that no resolve could show.

A sample keeps, for G culling slots of the shutter, the nearest depth by which a stored interval
already covers the slot (`occ[row, j]`, inf while uncovered; `occ[row, G]` is the farthest of
them, so a sample whose every slot is covered can stop early, and `occ[row, G + 1]` how many are
still uncovered, so the farthest is looked for only once none is: a row of 32 instants would
otherwise be scanned at every first cover; G = 0 switches culling off):
- span slots (above 32 bits and in exact mode: G = CULL_SLOTS in the package): slot j is the span
  [j/G, (j+1)/G], recorded only by an interval covering all of it (its farthest depth in the
  slot), so whatever lies behind it in the slot is hidden at every instant and every span there;
- instant slots (a bitmask resolve of B <= 32 bits; up to MAX_INSTANT_CULL_SLOTS when
  asked for): G = B and slot
  j is the resolve's own instant (j + 0.5)/B, the depth there taken from the interval's depth
  line, exactly as the resolve reads it (culls more, costs more: a stored interval updates every
  slot instant it holds).
An interval is dropped, and an entry skipped before its coverage is computed, when at each slot
it touches it lies behind the slot's depth by more than CULL_MARGIN (relative): some stored
interval is then in front of it wherever the resolve looks, so the resolve's result is the same
without it (the kept one is never dropped later: culling only removes what is behind). An entry
is skipped by its nearest vertex, or else (plane_hidden) by where the sample's ray meets its
plane over its span, bounded by Bernstein coefficients: a surface tilted or turning in depth
reaches far nearer with a vertex than where the ray meets it. Tile
lists run nearest first (bin_entries' near_depth), so the front layers fill the slots early and, once every
slot is covered, the walk stops at the first entry whose nearest depth is behind all of them.
"""

from __future__ import annotations

import warp as wp

from .moving import Moving, depth_polynomials
from .resolve import span_slots

MAX_INSTANT_CULL_SLOTS = 128   # instant slots are used up to this many time bits
CULL_MARGIN = 1.0e-5
# samples per fill launch band, so that each band's culling rows stay within ~64 MB
CULL_ROW_BYTES_BUDGET = 64 * 2**20
#: plane_hidden's room for float32 rounding: the plane must be beyond the slots' depth by
#: PLANE_SLACK (relative), and |D| at least PLANE_CONDITION of its rounding's size (rounding_size),
#: where the polynomials' depths and the intervals' own (computed in another form, moving.depth_at)
#: agree to ~1e-4: a degenerate or edge-on triangle gets no test
PLANE_SLACK = wp.constant(1.0e-3)
PLANE_CONDITION = wp.constant(1.0e-3)


@wp.func
def behind(z: float, z_occ: float) -> bool:
    """True when depth z is clearly behind depth z_occ (an uncovered slot has z_occ = inf)."""
    return z > z_occ + CULL_MARGIN * wp.abs(z_occ) + 1.0e-30


@wp.func
def touched_slots(t0: float, t1: float, g: int, whole: int) -> wp.vec2i:
    """Culling slots [j0, j1) that shutter span [t0, t1] reaches."""
    if whole == 0:
        return span_slots(t0, t1, g)
    j0 = wp.clamp(int(wp.floor(t0 * float(g))), 0, g - 1)
    j1 = wp.clamp(int(wp.ceil(t1 * float(g))), j0 + 1, g)
    return wp.vec2i(j0, j1)


@wp.func
def reset_slots(occ: wp.array2d(dtype=float), row: int, g: int, z: float):
    """Every slot covered at depth z (the sample's nearest static surface, or inf: then all G are
    uncovered, counted in occ[row, G + 1])."""
    for j in range(g + 1):
        occ[row, j] = z
    uncovered = float(0.0)
    if z == wp.inf:
        uncovered = float(g)
    occ[row, g + 1] = uncovered


@wp.func
def all_hidden(occ: wp.array2d(dtype=float), row: int, g: int, z_near: float) -> bool:
    """True when whatever lies nowhere nearer than z_near is behind every slot."""
    return g > 0 and behind(z_near, occ[row, g])


@wp.func
def slots_depth(occ: wp.array2d(dtype=float), row: int, g: int, whole: int, u0: float, u1: float,
                z_deep: float) -> float:
    """The farthest covered depth of the slots shutter time [u0, u1] reaches (inf when one of them
    is uncovered, or culling is off; -inf when it reaches none: a span between two instant slots
    has no bits, hidden wherever the resolve looks): what lies behind it there lies behind every
    one of them (an entry spanning [u0, u1] whose nearest vertex does is hidden at every slot it
    reaches). The scan stops once the depth reaches z_deep (an entry's farthest vertex): nothing of
    that entry is behind it then, and the depth so far says so."""
    if g == 0:
        return wp.inf
    slots = touched_slots(u0, u1, g, whole)
    z_far = float(-wp.inf)
    for j in range(slots[0], slots[1]):
        z_far = wp.max(z_far, occ[row, j])
        if z_far >= z_deep:
            return z_far
    return z_far


@wp.func
def depth_slope(t: wp.vec2, z: wp.vec2) -> float:
    """Change of an interval's depth per unit of shutter time (0 for an empty span): the slot
    loops below evaluate its depth line with one multiply-add per point instead of z_at's
    division (a rounding apart from z_at, far inside CULL_MARGIN)."""
    if t[1] <= t[0]:
        return 0.0
    return (z[1] - z[0]) / (t[1] - t[0])


@wp.func
def interval_hidden(occ: wp.array2d(dtype=float), row: int, g: int, whole: int, t: wp.vec2, z: wp.vec2) -> bool:
    """True when the interval (shutter span t, depth line z) is behind at every slot it reaches
    (in bitmask mode an interval that holds no slot instant is hidden too: it has no bits)."""
    if g == 0:
        return False
    slots = touched_slots(t[0], t[1], g, whole)
    k = depth_slope(t, z)
    inv_g = 1.0 / float(g)
    for j in range(slots[0], slots[1]):
        if whole == 0:
            if not behind(z[0] + k * ((float(j) + 0.5) * inv_g - t[0]), occ[row, j]):
                return False
        else:
            a = wp.max(t[0], float(j) * inv_g)
            b = wp.min(t[1], float(j + 1) * inv_g)
            # the nearer end of a linear piece: where its slope points back
            near_end = a
            if k < 0.0:
                near_end = b
            if not behind(z[0] + k * (near_end - t[0]), occ[row, j]):
                return False
    return True


@wp.func
def record_interval(occ: wp.array2d(dtype=float), row: int, g: int, whole: int, t: wp.vec2, z: wp.vec2):
    """Lower the slots' depths where the stored interval covers them (and the farthest of them)."""
    if g == 0:
        return
    j0 = int(0)
    j1 = int(0)
    if whole == 0:
        slots = span_slots(t[0], t[1], g)
        j0 = slots[0]
        j1 = slots[1]
    else:
        j0 = wp.clamp(int(wp.ceil(t[0] * float(g))), 0, g)
        j1 = wp.clamp(int(wp.floor(t[1] * float(g))), 0, g)
    z_max = occ[row, g]
    at_max = int(0)
    newly = int(0)   # slots this interval covers first (their farthest was inf)
    k = depth_slope(t, z)
    inv_g = 1.0 / float(g)
    for j in range(j0, j1):
        zj = float(0.0)
        if whole == 0:
            zj = z[0] + k * ((float(j) + 0.5) * inv_g - t[0])
        else:
            # the farther end of the slot on the depth line
            far_end = float(j + 1) * inv_g
            if k < 0.0:
                far_end = float(j) * inv_g
            zj = z[0] + k * (far_end - t[0])
        old = occ[row, j]
        if zj < old:
            occ[row, j] = zj
            if old == wp.inf:
                newly += 1
            elif old >= z_max:
                at_max = 1
    if newly > 0:   # the farthest stays inf while a slot is uncovered: found once none is
        left = occ[row, g + 1] - float(newly)
        occ[row, g + 1] = left
        if left <= 0.0:
            at_max = 1
    if at_max != 0:
        far = float(-wp.inf)
        for j in range(g):
            far = wp.max(far, occ[row, j])
        occ[row, g] = far


@wp.func
def bernstein_cubic(p: wp.vec4) -> wp.vec4:
    """Bernstein coefficients on [0, 1] of the cubic with power coefficients p (1, s, s², s³):
    the cubic lies within their range there (a quadratic has p[3] = 0)."""
    return wp.vec4(p[0], p[0] + p[1] / 3.0, p[0] + (2.0 * p[1] + p[2]) / 3.0, p[0] + p[1] + p[2] + p[3])


@wp.func
def rounding_size(m: Moving, o: wp.vec3, d: wp.vec3) -> float:
    """|d| × the farthest vertex from o × the edges' lengths and changes: the size of the float32
    rounding in d · n(s) over the span (the edges are differences of camera-space positions, each
    rounded to its own magnitude), to which plane_beyond compares D."""
    far = wp.max(wp.max(wp.max(wp.length_sq(m.a0 - o), wp.length_sq(m.b0 - o)), wp.max(wp.length_sq(m.c0 - o),
                                                                                      wp.length_sq(m.a1 - o))),
                 wp.max(wp.length_sq(m.b1 - o), wp.length_sq(m.c1 - o)))
    da = m.a1 - m.a0
    edges = (wp.length(m.b0 - m.a0) + wp.length((m.b1 - m.b0) - da) + wp.length(m.c0 - m.a0)
             + wp.length((m.c1 - m.c0) - da))
    return wp.length(d) * wp.sqrt(far) * edges


@wp.func
def plane_beyond(m: Moving, o: wp.vec3, d: wp.vec3, num: wp.vec4, den: wp.vec4, z: float) -> bool:
    """True when the depth N(s) / D(s) (moving.depth_polynomials of triangle m and ray (o, d))
    exceeds z by PLANE_SLACK (relative) at every entry time s in [0, 1]: where D keeps one sign,
    that is the sign of N - z D, and the Bernstein coefficients of that cubic bound it. Where D
    comes within PLANE_CONDITION of its rounding's size (rounding_size) of 0 (a degenerate
    triangle, a plane edge-on to the ray), the depths are too ill-conditioned to compare, and the
    answer is False (checked last: it costs more than the rest)."""
    bn = bernstein_cubic(num)
    bd = bernstein_cubic(den)
    sign = float(0.0)
    if bd[0] > 0.0 and bd[1] > 0.0 and bd[2] > 0.0 and bd[3] > 0.0:
        sign = 1.0
    elif bd[0] < 0.0 and bd[1] < 0.0 and bd[2] < 0.0 and bd[3] < 0.0:
        sign = -1.0
    else:
        return False
    z_clear = z + PLANE_SLACK * wp.abs(z)
    for i in range(4):
        if sign * (bn[i] - z_clear * bd[i]) <= 0.0:
            return False
    floor = PLANE_CONDITION * rounding_size(m, o, d)
    return wp.min(wp.min(sign * bd[0], sign * bd[1]), wp.min(sign * bd[2], sign * bd[3])) > floor


@wp.func
def plane_hidden(m: Moving, o: wp.vec3, d: wp.vec3, z_range: wp.vec2, z_slots: float) -> bool:
    """True when an entry (its triangle m, depth_range z_range) would store no interval at the
    sample's ray (o, d) under slots whose farthest covered depth is z_slots (slots_depth): its
    plane's depth along the ray is behind z_slots at every time of its span. Every interval it
    could store is a chord between two such depths (the ends of a covered piece), so
    interval_hidden would drop each one, and skipping the entry before its coverage is computed
    changes nothing. Sharper than its nearest vertex's depth where a surface is tilted in depth or
    turns; tested only where its farthest vertex is behind z_slots (the hits are convex
    combinations of the vertices), so entries in front of everything cost one comparison."""
    if not behind(z_range[1], z_slots):
        return False
    num, den = depth_polynomials(m, o, d)
    return plane_beyond(m, o, d, num, den, z_slots + CULL_MARGIN * wp.abs(z_slots) + 1.0e-30)
