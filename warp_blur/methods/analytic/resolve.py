"""Resolve per-pixel intervals into a colour: front-to-back, with crossings split in time.

Bitmask mode (time_bits B > 0): time slot j stands for the instant (j + 0.5)/B of the shutter,
so the result equals accumulation with B instants, without noise. Intervals are sorted by their
nearest depth; for each interval I in that order, the slots where a *later* interval J is in
front of I (their depth lines cross inside the common span: the crossing time splits the span)
are "stolen" from I. I contributes popcount(bits(I) & ~covered & ~stolen)/B × its radiance
(linear in time: taken at the mean time of those slots) and marks bits(I) & ~stolen covered; the
loop stops when every slot is covered. The background fills the uncovered slots; alpha is the
covered share.

Exact mode (time_bits 0): a sweep over time keeps the covered time as exact spans: at each event
(an interval starts or ends, or another interval crosses in front of the current front one) the
nearest interval changes; each span adds its length × the front radiance. No quantisation.
"""

from __future__ import annotations

import warp as wp

from ...kernel_types import View

WORD_ALL = wp.constant(wp.uint32(0xFFFFFFFF))


# An interval's radiance at its start (0:3) and end (3:6); linear in time between.
RadiancePair = wp.types.vector(length=6, dtype=wp.float32)


@wp.func
def radiance_pair(start: wp.vec3, end: wp.vec3) -> RadiancePair:
    return RadiancePair(start[0], start[1], start[2], end[0], end[1], end[2])


@wp.func
def radiance_at(c: RadiancePair, t: wp.vec2, time: float) -> wp.vec3:
    """Radiance of an interval spanning shutter times t at `time` (linear between its ends)."""
    r0 = wp.vec3(c[0], c[1], c[2])
    r1 = wp.vec3(c[3], c[4], c[5])
    f = float(0.5)
    if t[1] > t[0]:
        f = wp.clamp((time - t[0]) / (t[1] - t[0]), 0.0, 1.0)
    return r0 + (r1 - r0) * f


@wp.func
def popcount(x: wp.uint32) -> int:
    v = x - ((x >> wp.uint32(1)) & wp.uint32(0x55555555))
    v = (v & wp.uint32(0x33333333)) + ((v >> wp.uint32(2)) & wp.uint32(0x33333333))
    v = (v + (v >> wp.uint32(4))) & wp.uint32(0x0F0F0F0F)
    return int((v * wp.uint32(0x01010101)) >> wp.uint32(24))


@wp.func
def bit_index_sum(x: wp.uint32) -> int:
    """Sum of the indices (0..31) of the set bits of x."""
    return (popcount(x & wp.uint32(0xAAAAAAAA)) + 2 * popcount(x & wp.uint32(0xCCCCCCCC))
            + 4 * popcount(x & wp.uint32(0xF0F0F0F0)) + 8 * popcount(x & wp.uint32(0xFF00FF00))
            + 16 * popcount(x & wp.uint32(0xFFFF0000)))


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


@wp.kernel(enable_backward=False)
def resolve_bitmask(view: View, dome: wp.vec3, pixels: wp.array(dtype=int), spans: wp.array(dtype=wp.vec2i),
                    iv_t: wp.array(dtype=wp.vec2), iv_z: wp.array(dtype=wp.vec2),
                    iv_rgb: wp.array(dtype=RadiancePair), bits: int, weight: float, first: int, band_first: int,
                    # outputs
                    order: wp.array(dtype=int), masks: wp.array2d(dtype=wp.uint32), rgba: wp.array2d(dtype=float)):
    """rgba[pixels[k]] += weight × the resolved colour of listed sample k = first + tid (intervals
    spans[k][0]:spans[k][1] of the chunk's arrays); masks is per-thread scratch (band rows, 2×words)."""
    k = first + wp.tid()
    pix = pixels[k]
    row = k - band_first
    lo = spans[k][0]
    hi = spans[k][1]
    words = (bits + 31) // 32
    for w in range(2 * words):
        masks[row, w] = wp.uint32(0)
    sort_by_near_depth(order, iv_z, lo, hi)
    color = wp.vec3(0.0, 0.0, 0.0)
    covered = int(0)
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
                index_sum = int(0)
                for w in range(w0, w1):
                    mine = word_mask(si[0], si[1], w) & ~masks[row, words + w]
                    new = mine & ~masks[row, w]
                    count = popcount(new)
                    visible += count
                    index_sum += bit_index_sum(new) + 32 * w * count
                    masks[row, w] = masks[row, w] | mine
                covered += visible
                if visible > 0:
                    # radiance is linear in time: its visible slots sum to count × value at their mean time
                    t_mean = (float(index_sum) / float(visible) + 0.5) / float(bits)
                    color = color + radiance_at(iv_rgb[i], ti, t_mean) * (float(visible) / float(bits))
    color = color + dome * (float(bits - covered) / float(bits))
    rgba[pix, 0] = rgba[pix, 0] + weight * color[0]
    rgba[pix, 1] = rgba[pix, 1] + weight * color[1]
    rgba[pix, 2] = rgba[pix, 2] + weight * color[2]
    rgba[pix, 3] = rgba[pix, 3] + weight * float(covered) / float(bits)


@wp.kernel(enable_backward=False)
def resolve_exact(view: View, dome: wp.vec3, pixels: wp.array(dtype=int), spans: wp.array(dtype=wp.vec2i),
                  iv_t: wp.array(dtype=wp.vec2), iv_z: wp.array(dtype=wp.vec2),
                  iv_rgb: wp.array(dtype=RadiancePair), weight: float, first: int, max_events: int,
                  # outputs
                  truncated: wp.array(dtype=int), rgba: wp.array2d(dtype=float)):
    """rgba[pixels[k]] += weight × the exact time average of listed sample k = first + tid
    (intervals spans[k][0]:spans[k][1]; sweep over events; no quantisation)."""
    k = first + wp.tid()
    pix = pixels[k]
    lo = spans[k][0]
    hi = spans[k][1]
    color = wp.vec3(0.0, 0.0, 0.0)
    cover = float(0.0)
    tau = float(0.0)
    events = int(0)
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
        span = nxt - tau
        if front >= 0:
            color = color + radiance_at(iv_rgb[front], iv_t[front], tau + 0.5 * span) * span
            cover = cover + span
        else:
            color = color + dome * span
        tau = nxt
        events += 1
        if events >= max_events and tau < 1.0:
            # keep the front surface for the rest (counted: never silent)
            wp.atomic_add(truncated, 0, 1)
            if front >= 0:
                color = color + radiance_at(iv_rgb[front], iv_t[front], tau) * (1.0 - tau)
                cover = cover + (1.0 - tau)
            else:
                color = color + dome * (1.0 - tau)
            tau = 1.0
    rgba[pix, 0] = rgba[pix, 0] + weight * color[0]
    rgba[pix, 1] = rgba[pix, 1] + weight * color[1]
    rgba[pix, 2] = rgba[pix, 2] + weight * color[2]
    rgba[pix, 3] = rgba[pix, 3] + weight * cover
