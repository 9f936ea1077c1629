"""Resolve per-pixel intervals into a colour: front-to-back, with crossings split in time.

Bitmask mode (time_bits B > 0): time slot j stands for the instant (j + 0.5)/B of the shutter,
so the result equals accumulation with B instants, without noise. Intervals are sorted by their
nearest depth; for each interval I in that order, the slots where a *later* interval J is in
front of I (their depth lines cross inside the common span: the crossing time splits the span)
are "stolen" from I. I's visible slots are bits(I) & ~covered & ~stolen; only then is I shaded
(radiance.py): each of its linear sub-pieces contributes (its visible slots)/B × its radiance at
their mean time (an interval at most short_span(n) long: one shading at that mean; a still
surface under moving shadows that is partly hidden: one per piece between the shadow maps'
instants, shadow_pieces). I marks bits(I) & ~stolen covered; the loop stops when every slot is covered.
The background fills the uncovered slots; alpha is the covered share.

Exact mode (time_bits 0): a sweep over time keeps the covered time as exact spans: at each event
(an interval starts or ends, or another interval crosses in front of the current front one) the
nearest interval changes; each span adds the integral of the front interval's (piecewise linear)
radiance over it. No quantisation.
"""

from __future__ import annotations

import warp as wp

from ...kernels.dome import dome_along, dome_at, dome_over
from ...kernels.kernel_types import Geometry, Shading, View
from .moving import Moving, entry_moving, entry_time, sample_ray
from .junctions import take_junction
from .radiance import (boundary_radiance, lerp_in_time, radiance_at, radiance_plan, radiance_plan_known, shade_at,
                       span_radiance, static_receiver, sub_piece_time)

WORD_ALL = wp.constant(wp.uint32(0xFFFFFFFF))
# bits whose index has bit 0, 1, 2, 3, 4 set (module constants: inline literals above 2**31 make
# the generated C++ narrow them through int32, with a compiler warning)
INDEX_BIT_0 = wp.constant(wp.uint32(0xAAAAAAAA))
INDEX_BIT_1 = wp.constant(wp.uint32(0xCCCCCCCC))
INDEX_BIT_2 = wp.constant(wp.uint32(0xF0F0F0F0))
INDEX_BIT_3 = wp.constant(wp.uint32(0xFF00FF00))
INDEX_BIT_4 = wp.constant(wp.uint32(0xFFFF0000))
#: bits whose index is even (the half frame of the error estimate: methods/halves.py)
INDEX_EVEN = wp.constant(wp.uint32(0x55555555))
#: intervals at most this long (shutter fraction) are shaded once, at their visible slots' mean
SHORT_SPAN = wp.constant(1.0 / 16.0)


@wp.func
def short_span(n_shade_max: int) -> float:
    """Longest interval (shutter fraction) shaded once: a quarter of a shading piece when the
    cap n cuts the shutter into n pieces, 1/(4n), and never below SHORT_SPAN (1/16: caps of 4
    and more). A low cap is a cheap preset (draft's 2: intervals up to 1/8 shaded once)."""
    return wp.max(SHORT_SPAN, 0.25 / float(n_shade_max))


@wp.func
def popcount(x: wp.uint32) -> int:
    v = x - ((x >> wp.uint32(1)) & wp.uint32(0x55555555))
    v = (v & wp.uint32(0x33333333)) + ((v >> wp.uint32(2)) & wp.uint32(0x33333333))
    v = (v + (v >> wp.uint32(4))) & wp.uint32(0x0F0F0F0F)
    return int((v * wp.uint32(0x01010101)) >> wp.uint32(24))


@wp.func
def bit_index_sum(x: wp.uint32) -> int:
    """Sum of the indices (0..31) of the set bits of x."""
    return (popcount(x & INDEX_BIT_0) + 2 * popcount(x & INDEX_BIT_1) + 4 * popcount(x & INDEX_BIT_2)
            + 8 * popcount(x & INDEX_BIT_3) + 16 * popcount(x & INDEX_BIT_4))


@wp.func
def span_slots(t0: float, t1: float, bits: int) -> wp.vec2i:
    """Slots j with t0 <= (j + 0.5)/bits < t1, as [j0, j1)."""
    j0 = wp.clamp(int(wp.ceil(t0 * float(bits) - 0.5)), 0, bits)
    j1 = wp.clamp(int(wp.ceil(t1 * float(bits) - 0.5)), 0, bits)
    return wp.vec2i(j0, j1)


@wp.func
def word_mask(j0: int, j1: int, w: int) -> wp.uint32:
    """Bits of word w that lie in slots [j0, j1)."""
    lo = wp.max(j0 - 32 * w, 0)
    hi = wp.min(j1 - 32 * w, 32)
    if hi <= lo:
        return wp.uint32(0)
    upper = WORD_ALL
    if hi < 32:
        upper = (wp.uint32(1) << wp.uint32(hi)) - wp.uint32(1)
    lower = (wp.uint32(1) << wp.uint32(lo)) - wp.uint32(1)
    return upper & ~lower


@wp.func
def z_at(t: wp.vec2, z: wp.vec2, time: float) -> float:
    """Depth of an interval at `time` (linear between its ends)."""
    if t[1] <= t[0]:
        return z[0]
    return z[0] + (z[1] - z[0]) * (time - t[0]) / (t[1] - t[0])


@wp.func
def sort_by_near_depth(order: wp.array(dtype=int), iv_z: wp.array(dtype=wp.vec2), lo: int, hi: int):
    """Insertion sort of order[lo:hi] by each interval's nearest depth (stable: ties keep entry order)."""
    for i in range(lo, hi):
        order[i] = i
    for i in range(lo + 1, hi):
        k = order[i]
        key = wp.min(iv_z[k][0], iv_z[k][1])
        j = i - 1
        while j >= lo and wp.min(iv_z[order[j]][0], iv_z[order[j]][1]) > key:
            order[j + 1] = order[j]
            j -= 1
        order[j + 1] = k


@wp.func
def slot_sums(masks: wp.array2d(dtype=wp.uint32), row: int, col: int, j0: int, j1: int) -> wp.vec2i:
    """(count, index sum) of the set bits in slots [j0, j1) of the bit row masks[row, col:]."""
    count = int(0)
    index_sum = int(0)
    for w in range(j0 // 32, (j1 + 31) // 32):
        x = masks[row, col + w] & word_mask(j0, j1, w)
        c = popcount(x)
        count += c
        index_sum += bit_index_sum(x) + 32 * w * c
    return wp.vec2i(count, index_sum)


@wp.func
def shadow_pieces(view: View, geo: Geometry, sh: Shading, e: int, m: Moving, o: wp.vec3, d: wp.vec3, t: wp.vec2,
                  bits: int, masks: wp.array2d(dtype=wp.uint32), row: int, col: int) -> wp.vec3:
    """A constant-radiance interval (entry e, span t) whose shadows vary, over its visible slots
    (set bits of masks[row, col:]), / bits: shadow visibility is linear in time between the maps'
    instants, so each piece between them adds its visible slots × the radiance at their mean time."""
    times = sh.shadow_times
    color = wp.vec3(0.0, 0.0, 0.0)
    lo = t[0]
    for b in range(times + 1):
        hi = t[1]
        if b < times:
            hi = wp.min((float(b) + 0.5) / float(times), t[1])
        if hi > lo:
            slots = span_slots(lo, hi, bits)
            sums = slot_sums(masks, row, col, slots[0], slots[1])
            if sums[0] > 0:
                t_mean = (float(sums[1]) / float(sums[0]) + 0.5) / float(bits)
                share = float(sums[0]) / float(bits)
                color = color + shade_at(view, geo, sh, e, m, o, d, entry_time(m, t_mean)) * share
            lo = hi
    return color


@wp.func
def visible_radiance(view: View, geo: Geometry, sh: Shading, e: int, o: wp.vec3, d: wp.vec3, t: wp.vec2,
                     n_shade_max: int, lights_static: int, bits: int, masks: wp.array2d(dtype=wp.uint32), row: int,
                     col: int, known: int, known_a: wp.vec3, known_b: wp.vec3):
    """(colour, linear, radiance at the start, at the end, shading residual): the interval (entry
    e, shutter span t) shaded over its visible slots (the set bits of masks[row, col:]): the sum over them of its
    radiance, / bits. Each linear sub-piece adds (its visible slots) × its radiance at their mean
    time; sub-piece ends are shaded only for sub-pieces with visible slots. known, known_a,
    known_b: radiance_plan_known's (ends already shaded); linear = 1 when both ends returned are
    the interval's own radiance there. The residual estimates what the colour lacks where the
    radiance curves: a sub-piece's chord misses a parabola by 2/3 of its middle's deviation on
    average, the interval's middle deviation / n² (0 where the interval is not linear)."""
    m = entry_moving(geo, e)
    zero = wp.vec3(0.0, 0.0, 0.0)
    still = n_shade_max > 1 and sh.shadow_times > 1 and static_receiver(geo, sh, e, lights_static) != 0
    short = n_shade_max > 1 and t[1] - t[0] <= short_span(n_shade_max)
    if still or short:
        slots = span_slots(t[0], t[1], bits)
        sums = slot_sums(masks, row, col, slots[0], slots[1])
        if still and sums[0] < slots[1] - slots[0]:
            # still surface under moving shadows: averaged over the visible slots only, not the span
            return shadow_pieces(view, geo, sh, e, m, o, d, t, bits, masks, row, col), 0, zero, zero, zero
        if short:
            # short: one shading at the visible slots' mean time, shadows over their extent
            t_mean = (float(sums[1]) / float(sums[0]) + 0.5) / float(bits)
            share = float(sums[0]) / float(bits)
            return radiance_at(view, geo, sh, e, m, o, d, entry_time(m, t_mean), share) * share, 0, zero, zero, zero
    s_a = entry_time(m, t[0])
    s_b = entry_time(m, t[1])
    n, linear, la, lm, lb = radiance_plan_known(view, geo, sh, e, m, o, d, s_a, s_b, n_shade_max, lights_static,
                                                known, known_a, known_b)
    color = wp.vec3(0.0, 0.0, 0.0)
    r0 = la
    have_r0 = int(1)
    seen = float(0.0)
    for k in range(n):
        t0 = sub_piece_time(t, k, n)
        t1 = sub_piece_time(t, k + 1, n)
        slots = span_slots(t0, t1, bits)
        sums = slot_sums(masks, row, col, slots[0], slots[1])
        if sums[0] > 0:
            share = float(sums[0]) / float(bits)
            seen += share
            if linear == 0:
                color = color + la * share
            else:
                if have_r0 == 0:
                    r0 = boundary_radiance(view, geo, sh, e, m, o, d, s_a, s_b, k, n, la, lm, lb)
                r1 = boundary_radiance(view, geo, sh, e, m, o, d, s_a, s_b, k + 1, n, la, lm, lb)
                t_mean = (float(sums[1]) / float(sums[0]) + 0.5) / float(bits)
                color = color + lerp_in_time(r0, r1, t0, t1, t_mean) * share
                r0 = r1
                have_r0 = 1
        else:
            have_r0 = 0
    residual = zero
    if linear != 0:
        residual = (lm - 0.5 * (la + lb)) * (seen * (2.0 / 3.0) / float(n * n))
    return color, linear, la, lb, residual


@wp.func
def span_mean(view: View, geo: Geometry, sh: Shading, e: int, o: wp.vec3, d: wp.vec3, t: wp.vec2, a: float, b: float,
              n_shade_max: int, lights_static: int) -> wp.vec3:
    """Mean over shutter times [a, b] (inside t) of the interval's (entry e, shutter span t)
    piecewise linear radiance: each sub-piece overlapping [a, b] weighs in with its radiance at
    the overlap's middle. With b <= a, the radiance at a (clamped to t)."""
    m = entry_moving(geo, e)
    s_a = entry_time(m, t[0])
    s_b = entry_time(m, t[1])
    if b > a and n_shade_max > 1 and sh.shadow_times > 1 and static_receiver(geo, sh, e, lights_static) != 0:
        # still surface under moving shadows: shadows averaged over [a, b], not the whole span
        return span_radiance(view, geo, sh, e, m, o, d, entry_time(m, a), entry_time(m, b))
    n, linear, la, lm, lb = radiance_plan(view, geo, sh, e, m, o, d, s_a, s_b, n_shade_max, lights_static)
    if linear == 0:
        return la
    color = wp.vec3(0.0, 0.0, 0.0)
    for k in range(n):
        t0 = sub_piece_time(t, k, n)
        t1 = sub_piece_time(t, k + 1, n)
        lo = wp.max(a, t0)
        hi = wp.min(b, t1)
        point = b <= a and (a < t1 or k + 1 == n) and (a >= t0 or k == 0)
        if hi > lo or point:
            r0 = boundary_radiance(view, geo, sh, e, m, o, d, s_a, s_b, k, n, la, lm, lb)
            r1 = boundary_radiance(view, geo, sh, e, m, o, d, s_a, s_b, k + 1, n, la, lm, lb)
            if point:
                return lerp_in_time(r0, r1, t0, t1, a)
            color = color + lerp_in_time(r0, r1, t0, t1, 0.5 * (lo + hi)) * ((hi - lo) / (b - a))
    return color


@wp.func
def dome_uncovered(sh: Shading, d: wp.vec3, masks: wp.array2d(dtype=wp.uint32), row: int, words: int, bits: int,
                   covered: int) -> wp.vec3:
    """The dome along d integrated over the time slots no surface covers (bits clear in
    masks[row, 0:words]), as a fraction of the shutter: one lookup per 8 slots when the camera
    turns, one in all when it holds."""
    if sh.dome_binding < 0 or sh.dome_segments == 0:
        return dome_along(sh, d) * (float(bits - covered) / float(bits))
    acc = wp.vec3(0.0, 0.0, 0.0)
    for c in range((bits + 7) // 8):
        w = c // 4
        free = popcount(word_mask(8 * c, wp.min(8 * c + 8, bits), w) & ~masks[row, w])
        if free > 0:
            slot_mid = 0.5 * float(8 * c + wp.min(8 * c + 8, bits))
            acc = acc + dome_at(sh, d, slot_mid / float(bits)) * float(free)
    return acc / float(bits)


@wp.func
def run_color(view: View, geo: Geometry, sh: Shading, o: wp.vec3, d: wp.vec3,
              iv_t: wp.array(dtype=wp.vec2), iv_e: wp.array(dtype=int), front: int, a: float, b: float,
              n_shade_max: int, lights_static: int, shaded: wp.array(dtype=int)) -> wp.vec3:
    """Integral over shutter times [a, b] of interval `front` (the dome when front < 0); counts
    the shading in shaded[0]."""
    if b <= a:
        return wp.vec3(0.0, 0.0, 0.0)
    if front < 0:
        return dome_over(sh, d, a, b) * (b - a)
    shaded[0] = shaded[0] + 1
    return span_mean(view, geo, sh, iv_e[front], o, d, iv_t[front], a, b, n_shade_max, lights_static) * (b - a)


@wp.kernel(enable_backward=False)
def resolve_bitmask(view: View, geo: Geometry, sh: Shading, sub: wp.vec2, n_shade_max: int, lights_static: int,
                    pixels: wp.array(dtype=int), spans: wp.array(dtype=wp.vec2i),
                    iv_t: wp.array(dtype=wp.vec2), iv_z: wp.array(dtype=wp.vec2), iv_e: wp.array(dtype=int), bits: int,
                    keep_still: int, junctions: int, weight: float, first: int, band_first: int,
                    # outputs
                    order: wp.array(dtype=int), masks: wp.array2d(dtype=wp.uint32), shaded: wp.array(dtype=int),
                    reused: wp.array(dtype=int), rgba: wp.array2d(dtype=float), half_diff: wp.array2d(dtype=float)):
    """rgba[pixels[k]] += weight × the resolved colour of listed sample k = first + tid (intervals
    spans[k][0]:spans[k][1] of the chunk's arrays, at sub-pixel position sub); masks is per-thread
    scratch (band rows, 3 × words: covered, stolen, visible); shaded[0] counts the intervals shaded.
    keep_still = 1 (lights that hold still, shadow maps of one instant): a still entry's radiance is
    the same over all its intervals (its every piece is shaded as one constant, at any time the
    same), so it is shaded once a sample and each of its intervals adds it × its visible share.
    junctions (bits, junction()): a linear interval that starts or ends where one of the last two
    linear intervals shaded meets it at the same point at the same time takes that interval's
    radiance there instead of shading it again: bit 0 at a motion-segment junction of the same
    triangle (or where one entry's span was cut in pieces), bit 1 across the edge two smooth
    neighbours share. reused[0] counts the ends taken (the ends of linear intervals only: a short
    or still one is shaded otherwise). half_diff[pixels[k]] (when it has a row per pixel) += weight ×
    (the colour − the colour of the even-indexed slots alone, each interval's radiance taken as its
    mean over its visible slots), for the frame's error estimate (methods/halves.py)."""
    k = first + wp.tid()
    pix = pixels[k]
    row = k - band_first
    lo = spans[k][0]
    hi = spans[k][1]
    words = (bits + 31) // 32
    for w in range(3 * words):
        masks[row, w] = wp.uint32(0)
    sort_by_near_depth(order, iv_z, lo, hi)
    o, d = sample_ray(view, pix % view.width, pix // view.width, sub)
    color = wp.vec3(0.0, 0.0, 0.0)
    half = wp.vec3(0.0, 0.0, 0.0)   # colour minus the even slots' colour
    covered = int(0)
    covered_even = int(0)
    kept_e = int(-1)
    kept_r = wp.vec3(0.0, 0.0, 0.0)
    # the last two linear intervals shaded (entry, shutter span, radiance at both ends): an
    # interval that meets one at a motion-segment junction of the same triangle takes its
    # radiance there instead of shading the same point again
    j1_e = int(-1)
    j1_t = wp.vec2(0.0, 0.0)
    j1_a = wp.vec3(0.0, 0.0, 0.0)
    j1_b = wp.vec3(0.0, 0.0, 0.0)
    j2_e = int(-1)
    j2_t = wp.vec2(0.0, 0.0)
    j2_a = wp.vec3(0.0, 0.0, 0.0)
    j2_b = wp.vec3(0.0, 0.0, 0.0)
    for ii in range(lo, hi):
        if covered < bits:
            i = order[ii]
            ti = iv_t[i]
            zi = iv_z[i]
            si = span_slots(ti[0], ti[1], bits)
            if si[1] > si[0]:
                w0 = si[0] // 32
                w1 = (si[1] + 31) // 32
                for w in range(w0, w1):
                    masks[row, words + w] = wp.uint32(0)
                zmax_i = wp.max(zi[0], zi[1])
                # later intervals in front of I somewhere in the common span steal those slots
                jj = ii + 1
                while jj < hi:
                    j = order[jj]
                    zj = iv_z[j]
                    if wp.min(zj[0], zj[1]) >= zmax_i:
                        break
                    tj = iv_t[j]
                    a = wp.max(ti[0], tj[0])
                    b = wp.min(ti[1], tj[1])
                    if b > a:
                        da = z_at(tj, zj, a) - z_at(ti, zi, a)
                        db = z_at(tj, zj, b) - z_at(ti, zi, b)
                        s0 = a
                        s1 = a
                        if da < 0.0 and db < 0.0:
                            s1 = b
                        elif da < 0.0:
                            s1 = a + (b - a) * da / (da - db)
                        elif db < 0.0:
                            s0 = a + (b - a) * da / (da - db)
                            s1 = b
                        if s1 > s0:
                            sj = span_slots(s0, s1, bits)
                            for w in range(sj[0] // 32, (sj[1] + 31) // 32):
                                masks[row, words + w] = masks[row, words + w] | word_mask(sj[0], sj[1], w)
                    jj += 1
                visible = int(0)
                visible_even = int(0)
                for w in range(w0, w1):
                    mine = word_mask(si[0], si[1], w) & ~masks[row, words + w]
                    new = mine & ~masks[row, w]
                    masks[row, 2 * words + w] = new
                    visible += popcount(new)
                    visible_even += popcount(new & INDEX_EVEN)
                    masks[row, w] = masks[row, w] | mine
                covered += visible
                covered_even += visible_even
                before = color
                if visible > 0:
                    e = iv_e[i]
                    if keep_still != 0 and geo.entry_k0[e] == geo.entry_k1[e]:
                        if e != kept_e:
                            shaded[0] = shaded[0] + 1
                            kept_e = e
                            kept_r = shade_at(view, geo, sh, e, entry_moving(geo, e), o, d, 0.5)
                        color = color + kept_r * (float(visible) / float(bits))
                    else:
                        shaded[0] = shaded[0] + 1
                        known = int(0)
                        known_a = wp.vec3(0.0, 0.0, 0.0)
                        known_b = wp.vec3(0.0, 0.0, 0.0)
                        if junctions != 0:
                            known, known_a, known_b = take_junction(geo, sh, e, ti, j1_e, j1_t, j1_a, j1_b, known,
                                                                    known_a, known_b, junctions)
                            known, known_a, known_b = take_junction(geo, sh, e, ti, j2_e, j2_t, j2_a, j2_b, known,
                                                                    known_a, known_b, junctions)
                        c, linear, ra, rb, residual = visible_radiance(view, geo, sh, e, o, d, ti, n_shade_max,
                                                                       lights_static, bits, masks, row, 2 * words,
                                                                       known, known_a, known_b)
                        color = color + c
                        half = half + residual
                        if linear != 0:
                            reused[0] = reused[0] + (known & 1) + known // 2
                            j2_e = j1_e
                            j2_t = j1_t
                            j2_a = j1_a
                            j2_b = j1_b
                            j1_e = e
                            j1_t = ti
                            j1_a = ra
                            j1_b = rb
                    half = half + (color - before) * (1.0 - 2.0 * float(visible_even) / float(visible))
    dome = dome_uncovered(sh, d, masks, row, words, bits, covered)
    color = color + dome
    if half_diff.shape[0] > pix:
        if covered < bits:
            half = half + dome * (1.0 - float(bits - 2 * covered_even) / float(bits - covered))
        cover_half = float(covered - 2 * covered_even) / float(bits)
        half_diff[pix, 0] = half_diff[pix, 0] + weight * half[0]
        half_diff[pix, 1] = half_diff[pix, 1] + weight * half[1]
        half_diff[pix, 2] = half_diff[pix, 2] + weight * half[2]
        half_diff[pix, 3] = half_diff[pix, 3] + weight * cover_half
    rgba[pix, 0] = rgba[pix, 0] + weight * color[0]
    rgba[pix, 1] = rgba[pix, 1] + weight * color[1]
    rgba[pix, 2] = rgba[pix, 2] + weight * color[2]
    rgba[pix, 3] = rgba[pix, 3] + weight * float(covered) / float(bits)


@wp.kernel(enable_backward=False)
def resolve_exact(view: View, geo: Geometry, sh: Shading, sub: wp.vec2, n_shade_max: int, lights_static: int,
                  pixels: wp.array(dtype=int), spans: wp.array(dtype=wp.vec2i),
                  iv_t: wp.array(dtype=wp.vec2), iv_z: wp.array(dtype=wp.vec2), iv_e: wp.array(dtype=int),
                  weight: float, first: int, max_events: int,
                  # outputs
                  truncated: wp.array(dtype=int), shaded: wp.array(dtype=int), rgba: wp.array2d(dtype=float)):
    """rgba[pixels[k]] += weight × the exact time average of listed sample k = first + tid
    (intervals spans[k][0]:spans[k][1]; sweep over events; no quantisation); shaded[0] counts the
    runs of spans with one front interval, each shaded once."""
    k = first + wp.tid()
    pix = pixels[k]
    lo = spans[k][0]
    hi = spans[k][1]
    o, d = sample_ray(view, pix % view.width, pix // view.width, sub)
    color = wp.vec3(0.0, 0.0, 0.0)
    cover = float(0.0)
    tau = float(0.0)
    events = int(0)
    run_front = int(-1)
    run_start = float(0.0)
    while tau < 1.0:
        # the front interval just after tau
        front = int(-1)
        zf = float(0.0)
        slope_f = float(0.0)
        for i in range(lo, hi):
            t = iv_t[i]
            if t[0] <= tau and tau < t[1]:
                z = iv_z[i]
                zi = z_at(t, z, tau)
                slope = (z[1] - z[0]) / wp.max(t[1] - t[0], 1.0e-30)
                if front < 0 or zi < zf or (zi == zf and slope < slope_f):
                    front = i
                    zf = zi
                    slope_f = slope
        nxt = float(1.0)
        for i in range(lo, hi):
            t = iv_t[i]
            if t[0] > tau and t[0] < nxt:
                nxt = t[0]
            if t[0] <= tau and t[1] > tau and t[1] < nxt:
                nxt = t[1]
        if front >= 0:
            tf = iv_t[front]
            zfv = iv_z[front]
            for i in range(lo, hi):
                t = iv_t[i]
                if i != front and t[0] <= tau and t[1] > tau:
                    b = wp.min(t[1], tf[1])
                    z = iv_z[i]
                    da = z_at(t, z, tau) - z_at(tf, zfv, tau)
                    db = z_at(t, z, b) - z_at(tf, zfv, b)
                    if da >= 0.0 and db < 0.0:
                        tc = tau + (b - tau) * da / (da - db)
                        if tc > tau and tc < nxt:
                            nxt = tc
        if nxt <= tau:
            nxt = wp.min(tau + 1.0e-7, 1.0)
        if front != run_front:
            # the run of spans with one front ends: its radiance is integrated over the whole run
            color = color + run_color(view, geo, sh, o, d, iv_t, iv_e, run_front, run_start, tau, n_shade_max,
                                      lights_static, shaded)
            run_front = front
            run_start = tau
        if front >= 0:
            cover = cover + (nxt - tau)
        tau = nxt
        events += 1
        if events >= max_events and tau < 1.0:
            # keep the front surface for the rest (counted: never silent)
            wp.atomic_add(truncated, 0, 1)
            color = color + run_color(view, geo, sh, o, d, iv_t, iv_e, run_front, run_start, tau, n_shade_max,
                                      lights_static, shaded)
            if front >= 0:
                color = color + span_mean(view, geo, sh, iv_e[front], o, d, iv_t[front], tau, tau, n_shade_max,
                                          lights_static) * (1.0 - tau)
                cover = cover + (1.0 - tau)
            else:
                color = color + dome_over(sh, d, tau, 1.0) * (1.0 - tau)
            run_start = 1.0
            tau = 1.0
    color = color + run_color(view, geo, sh, o, d, iv_t, iv_e, run_front, run_start, 1.0, n_shade_max,
                              lights_static, shaded)
    rgba[pix, 0] = rgba[pix, 0] + weight * color[0]
    rgba[pix, 1] = rgba[pix, 1] + weight * color[1]
    rgba[pix, 2] = rgba[pix, 2] + weight * color[2]
    rgba[pix, 3] = rgba[pix, 3] + weight * cover
