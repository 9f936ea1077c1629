"""Occlusion culling in the fill pass: intervals and whole entries that no resolve could show.

A sample keeps, for G culling slots of the shutter, the nearest depth by which a stored interval
already covers the slot (`occ[row, j]`, inf while uncovered; `occ[row, G]` is the farthest of
them, so a sample whose every slot is covered can stop early, and `occ[row, G + 1]` how many are
still uncovered, so the farthest is looked for only once none is: a row of 32 instants would
otherwise be scanned at every first cover; G = 0 switches culling off):
- span slots (above 32 bits and in exact mode: G = CULL_SLOTS in the package): slot j is the span
  [j/G, (j+1)/G], recorded only by an interval covering all of it (its farthest depth in the
  slot), so whatever lies behind it in the slot is hidden at every instant and every span there;
- instant slots (a bitmask resolve of B <= 32 bits, the draft's; up to MAX_INSTANT_CULL_SLOTS when
  asked for): G = B and slot
  j is the resolve's own instant (j + 0.5)/B, the depth there taken from the interval's depth
  line, exactly as the resolve reads it (culls more, costs more: a stored interval updates every
  slot instant it holds).
An interval is dropped, and an entry skipped before its coverage is computed, when at each slot
it touches it lies behind the slot's depth by more than CULL_MARGIN (relative): some stored
interval is then in front of it wherever the resolve looks, so the resolve's result is the same
without it (the kept one is never dropped later: culling only removes what is behind). Tile
lists run nearest first (bin order_key), so the front layers fill the slots early and, once every
slot is covered, the walk stops at the first entry whose nearest depth is behind all of them.
"""

from __future__ import annotations

import warp as wp

from .resolve import span_slots

MAX_INSTANT_CULL_SLOTS = 128   # instant slots are used up to this many time bits
CULL_MARGIN = 1.0e-5
# samples per fill launch band, so that each band's culling rows stay within ~64 MB
CULL_ROW_BYTES_BUDGET = 64 * 2**20


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
def entry_hidden(occ: wp.array2d(dtype=float), row: int, g: int, whole: int, u0: float, u1: float,
                 z_near: float) -> bool:
    """True when an entry spanning shutter time [u0, u1], nowhere nearer than z_near, is behind
    the covered depth of every slot it reaches."""
    if g == 0:
        return False
    slots = touched_slots(u0, u1, g, whole)
    for j in range(slots[0], slots[1]):
        if not behind(z_near, occ[row, j]):
            return False
    return True


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
