"""Per-pixel coverage intervals of moving triangles, exactly (classify pass and fill pass).

An entry's vertices move linearly in camera space over its span; where it covers a pixel ray is
found exactly by coverage.py (edge-function quadratics, their roots, a sign test per piece).
Each covered piece is then:
- clipped to the near/far planes: where the entry's vertex depths straddle a plane, the view
  depth is sampled at 9 points and crossings are found by bisection to 1/16 of a time slot (a
  *sampled fallback*, counted in the stats as `near_far_fallbacks`);
- split where view depth is far from linear (checked at the midpoint), each piece stored as an
  interval (u0, u1, z0, z1, entry); a cutout entry's piece keeps only the time slots where the
  point it shows is not cut out (emit_visible). Nothing is shaded here: the resolve shades the intervals it
  finds visible (radiance.py), so hidden ones cost only their coverage.
The classify pass finds each sample's nearest static surface and whether any moving entry's swept
box holds it in front of that surface (no coverage, no shading; a sample none does is shaded and
resolved there, like a sharp render); the fill pass computes and stores the intervals of the samples it lists in one go, each
in a span of room, and reports how many there were, so a sample that needed more room is filled
again with exactly that much.
"""

from __future__ import annotations

import warp as wp

from ...kernels.cutout import cutout_hides, cutout_opacity, has_cutout, is_fractional, opacity_hides
from ...kernels.dome import dome_over
from ...kernels.kernel_types import Bins, Geometry, Shading, View
from ...kernels.raster import add_pixel, box_rejects, list_beyond, pixel_tile
from ...kernels.rays import intersect_triangle, static_entry_hit
from .coverage import MAX_SPAN_PIECES, entry_edges, next_breakpoint, piece_covered
from .occlusion import all_hidden, behind, interval_hidden, plane_hidden, record_interval, reset_slots, slots_depth
from .moving import (Moving, depth_at, depth_polynomials, depth_range, entry_moving, eye_relative, in_range, in_range_at,
                     plane_hit, sample_ray)
from .radiance import boundary_radiance, lerp_in_time, radiance_plan, sub_piece_time
from .resolve import span_slots

MAX_PIECES = 16
CLIP_SAMPLES = 8


# inlined into each caller (it takes no struct): fill's hot path stores intervals without a call
@wp.func(inline=True)
def emit_pieces(e: int, m: Moving, o: wp.vec3, d: wp.vec3, s_a: float, s_b: float, limit: int, base: int,
                iv_t: wp.array(dtype=wp.vec2), iv_z: wp.array(dtype=wp.vec2), iv_e: wp.array(dtype=int),
                occ: wp.array2d(dtype=float), row: int, g: int, whole: int) -> int:
    """Store [s_a, s_b] of entry e (already known covered and within the clipping range) as
    intervals at base, base + 1, ... (those below `limit` only: limit 0 counts), split where view
    depth is far from linear (its middle off the ends' mean by more than 1e-3 of the depth),
    leaving out those the sample's culling slots hide (occlusion.py); returns how many it kept.
    Radiance is left to the resolve (radiance.py)."""
    z_a = depth_at(m, o, d, s_a)
    z_b = depth_at(m, o, d, s_b)
    z_m = depth_at(m, o, d, 0.5 * (s_a + s_b))
    tol = 1.0e-3 * wp.max(wp.abs(z_a), wp.abs(z_b))
    err = wp.abs(z_m - 0.5 * (z_a + z_b))
    n = int(1)
    if err > tol and tol > 0.0:
        n = wp.min(int(wp.ceil(wp.sqrt(err / tol))), MAX_PIECES)
    du = m.u1 - m.u0
    z_prev = z_a
    kept = int(0)
    for i in range(n):
        s0 = s_a + (s_b - s_a) * float(i) / float(n)
        s1 = s_a + (s_b - s_a) * float(i + 1) / float(n)
        z1 = z_b
        if i + 1 < n:
            z1 = depth_at(m, o, d, s1)
        t = wp.vec2(m.u0 + s0 * du, m.u0 + s1 * du)
        z = wp.vec2(z_prev, z1)
        if not interval_hidden(occ, row, g, whole, t, z):
            if base + kept < limit:
                iv_t[base + kept] = t
                iv_z[base + kept] = z
                iv_e[base + kept] = e
            record_interval(occ, row, g, whole, t, z)
            kept += 1
        z_prev = z1
    return kept


@wp.func
def emit_visible(geo: Geometry, e: int, m: Moving, o: wp.vec3, d: wp.vec3, sx: float, sy: float, s_a: float,
                 s_b: float, limit: int, base: int, iv_t: wp.array(dtype=wp.vec2), iv_z: wp.array(dtype=wp.vec2),
                 iv_e: wp.array(dtype=int), occ: wp.array2d(dtype=float), row: int, g: int, whole: int) -> int:
    """emit_pieces, except that the piece of an entry with an opacity test (kernels/cutout.py: a
    moving cutout, or any fractional opacity) is first cut at the time slots (geo.cutout_slots
    per shutter), each slot's part kept only where the point hit at the slot's centre (clamped
    into the piece) is there for the sample at (sx, sy), and the kept runs emitted: the opacity is
    point-sampled at the instants of accumulation with that many instants."""
    tri = geo.entry_tri[e]
    du = m.u1 - m.u0
    if not has_cutout(geo, tri) or du <= 0.0:
        return emit_pieces(e, m, o, d, s_a, s_b, limit, base, iv_t, iv_z, iv_e, occ, row, g, whole)
    r = float(geo.cutout_slots)
    u_a = m.u0 + s_a * du
    u_b = m.u0 + s_b * du
    k_a = wp.clamp(int(wp.floor(u_a * r)), 0, geo.cutout_slots - 1)
    k_b = wp.clamp(int(wp.floor(u_b * r)), k_a, geo.cutout_slots - 1)
    # a still entry shows the same point in every slot: its hit and opacity are found once, and
    # only its presence is tested per slot (a fractional one's translucency)
    still = geo.entry_k0[e] == geo.entry_k1[e]
    opacity = float(0.0)
    if still:
        hit_still = plane_hit(o, d, m.a0, m.b0, m.c0)
        opacity = cutout_opacity(geo, tri, hit_still[2], hit_still[3])
    kept = int(0)
    run = float(-1.0)   # entry time where the current run of kept slots starts (-1: none)
    for k in range(k_a, k_b + 1):
        lo = wp.max(u_a, float(k) / r)
        hi = wp.min(u_b, float(k + 1) / r)
        if hi > lo or k == k_a:
            s_c = (wp.clamp((float(k) + 0.5) / r, lo, hi) - m.u0) / du
            s_lo = wp.max(s_a, (lo - m.u0) / du)
            hides = False
            if still:
                hides = opacity_hides(geo, tri, opacity, m.u0 + s_c * du, sx, sy)
            else:
                hit = plane_hit(o, d, m.a0 + s_c * (m.a1 - m.a0), m.b0 + s_c * (m.b1 - m.b0),
                                m.c0 + s_c * (m.c1 - m.c0))
                hides = cutout_hides(geo, tri, hit[2], hit[3], m.u0 + s_c * du, sx, sy)
            if hides:
                if run >= 0.0 and s_lo > run:
                    kept += emit_pieces(e, m, o, d, run, s_lo, limit, base + kept, iv_t, iv_z, iv_e, occ, row, g,
                                        whole)
                run = -1.0
            elif run < 0.0:
                run = s_lo
    if run >= 0.0 and s_b > run:
        kept += emit_pieces(e, m, o, d, run, s_b, limit, base + kept, iv_t, iv_z, iv_e, occ, row, g, whole)
    return kept


@wp.func
def clip_steps(bits: int, width: float) -> int:
    """Bisection steps that narrow a near/far crossing's bracket of `width` (shutter time) to 1/16
    of a time slot (1/bits of the shutter): the resolve cannot tell the crossing apart more finely.
    Exact mode (bits 0) bisects 24 times (float32's resolution of the piece)."""
    if bits <= 0:
        return 24
    n = int(0)
    w = width * float(16 * bits)
    while w > 1.0 and n < 24:
        w = w * 0.5
        n += 1
    return n


@wp.func
def emit_clipped(view: View, geo: Geometry, e: int, m: Moving, o: wp.vec3, d: wp.vec3, sx: float, sy: float, s_a: float,
                 s_b: float, may_clip: int,
                 limit: int, base: int, iv_t: wp.array(dtype=wp.vec2), iv_z: wp.array(dtype=wp.vec2),
                 iv_e: wp.array(dtype=int), fallbacks: wp.array(dtype=int), occ: wp.array2d(dtype=float), row: int,
                 g: int, whole: int) -> int:
    """Emit the part of a covered piece inside the clipping range (sampled when it may cross)."""
    if may_clip == 0:
        if not has_cutout(geo, geo.entry_tri[e]):   # the common case, without emit_visible's copy of geo
            return emit_pieces(e, m, o, d, s_a, s_b, limit, base, iv_t, iv_z, iv_e, occ, row, g, whole)
        return emit_visible(geo, e, m, o, d, sx, sy, s_a, s_b, limit, base, iv_t, iv_z, iv_e, occ, row, g, whole)
    wp.atomic_add(fallbacks, 0, 1)
    count = int(0)
    prev_s = s_a
    # the depth as a ratio of polynomials in s: each sample and bisection step costs a few
    # multiplications instead of depth_at's cross product
    num, den = depth_polynomials(m, o, d)
    prev_in = in_range_at(view, num, den, s_a)
    start = s_a
    steps = clip_steps(geo.clip_bits, (s_b - s_a) / float(CLIP_SAMPLES) * (m.u1 - m.u0))
    for i in range(1, CLIP_SAMPLES + 1):
        s = s_a + (s_b - s_a) * float(i) / float(CLIP_SAMPLES)
        now_in = in_range_at(view, num, den, s)
        if now_in != prev_in:
            lo = prev_s
            hi = s
            for _k in range(steps):
                mid = 0.5 * (lo + hi)
                if in_range_at(view, num, den, mid) == prev_in:
                    lo = mid
                else:
                    hi = mid
            if prev_in:
                # leaving the range: keep [start, lo] (the inside end of the bracket)
                if lo > start:
                    count += emit_visible(geo, e, m, o, d, sx, sy, start, lo, limit, base + count, iv_t, iv_z, iv_e, occ, row, g,
                                         whole)
            else:
                start = hi
        prev_in = now_in
        prev_s = s
    if prev_in and s_b > start:
        count += emit_visible(geo, e, m, o, d, sx, sy, start, s_b, limit, base + count, iv_t, iv_z, iv_e, occ, row, g,
                              whole)
    return count


@wp.func
def entry_intervals(view: View, geo: Geometry, e: int, m: Moving, o: wp.vec3, d: wp.vec3, sx: float, sy: float,
                    limit: int, base: int,
                    iv_t: wp.array(dtype=wp.vec2), iv_z: wp.array(dtype=wp.vec2), iv_e: wp.array(dtype=int),
                    fallbacks: wp.array(dtype=int), occ: wp.array2d(dtype=float), row: int, g: int,
                    whole: int) -> int:
    """The number of coverage intervals of entry e (its triangle m = entry_moving(geo, e)) at a
    pixel ray, stored at base, base + 1, ... where below `limit` (limit 0 only counts)."""
    vi = geo.tri_vertices[geo.entry_tri[e]]
    if geo.entry_k0[e] == geo.entry_k1[e]:
        # static entry: covered for the whole shutter or never
        hit = intersect_triangle(o, d, m.a0, m.b0, m.c0, vi)
        if hit[0] == 0.0 or not in_range(view, hit[1]):
            return 0
        if is_fractional(geo, geo.entry_tri[e]):   # there in some time slots
            return emit_visible(geo, e, m, o, d, sx, sy, 0.0, 1.0, limit, base, iv_t, iv_z, iv_e, occ, row, g, whole)
        if cutout_hides(geo, geo.entry_tri[e], hit[2], hit[3], 0.5, sx, sy):
            return 0
        return emit_pieces(e, m, o, d, 0.0, 1.0, limit, base, iv_t, iv_z, iv_e, occ, row, g, whole)
    a0, b0, c0, da, db, dc = eye_relative(m, o)
    ca, cb, cc, ra, rb, rc, dga, dgb, dgc = entry_edges(view, geo, e, d, a0, da, b0, db, c0, dc, vi)
    # may the view depth leave [near, far]? (the hit is a convex combination of the vertices)
    z_range = depth_range(m)
    may_clip = int(0)
    if z_range[0] < view.near or z_range[1] > view.far:
        may_clip = 1
    count = int(0)
    s_prev = float(0.0)
    for _step in range(MAX_SPAN_PIECES):
        if s_prev < 1.0:
            s_next = next_breakpoint(ra, rb, rc, s_prev)
            sm = 0.5 * (s_prev + s_next)
            if piece_covered(ca, cb, cc, dga, dgb, dgc, a0, da, b0, db, c0, dc, vi, sm, 0) != 0:
                count += emit_clipped(view, geo, e, m, o, d, sx, sy, s_prev, s_next, may_clip, limit, base + count, iv_t, iv_z,
                                      iv_e, fallbacks, occ, row, g, whole)
            s_prev = s_next
    return count


@wp.func
def nearest_static(view: View, geo: Geometry, static_bins: Bins, tile: int, sx: float, sy: float, o: wp.vec3,
                   d: wp.vec3):
    """(entry, depth) of the nearest static entry hit by the sample's ray, or (-1, inf). It covers
    the whole shutter, so static surfaces behind it never show: static geometry costs what a
    sharp render's visibility costs. The lists run nearest first: the walk stops at the first
    entry wholly beyond the hit it has."""
    e_static = int(-1)
    z_static = float(wp.inf)
    for i in range(static_bins.tile_offsets[tile], static_bins.tile_offsets[tile + 1]):
        e = static_bins.tile_entries[i]
        if e_static >= 0 and static_bins.near_sorted != 0 and list_beyond(static_bins, e, z_static):
            break
        if not box_rejects(static_bins, e, sx, sy):
            hit = static_entry_hit(geo, e, o, d)
            if hit[0] > 0.0 and in_range(view, hit[1]) and hit[1] < z_static \
                    and not cutout_hides(geo, geo.entry_tri[e], hit[2], hit[3], 0.5, sx, sy):
                z_static = hit[1]
                e_static = e
    return e_static, z_static


@wp.func
def may_show(view: View, m: Moving, z_static: float) -> bool:
    """False when the entry lies entirely behind the nearest static surface (depth z_static)."""
    return view.ortho != 0 or depth_range(m)[0] <= z_static


@wp.func
def moving_intervals(view: View, geo: Geometry, moving_bins: Bins, tile: int, start: int, sx: float, sy: float,
                     o: wp.vec3, d: wp.vec3, z_static: float, limit: int, base: int, iv_t: wp.array(dtype=wp.vec2),
                     iv_z: wp.array(dtype=wp.vec2), iv_e: wp.array(dtype=int), fallbacks: wp.array(dtype=int),
                     occ: wp.array2d(dtype=float), row: int, g: int, whole: int, skipped: wp.array(dtype=int)) -> int:
    """Count, and store below `limit`, the intervals of the moving entries at a sample, from the
    tile's list position `start` on (first_candidate found none before it), skipping those
    entirely behind the nearest static surface (depth z_static) or the culling slots (by their
    nearest vertex, or by their plane's depth along the ray: counted in skipped[0]). Where the
    list runs nearest first (the frame's bins do), the walk ends at the first entry behind every
    slot; in a list in entry order (tests' reference) such an entry is only skipped."""
    n = int(0)
    for i in range(start, moving_bins.tile_offsets[tile + 1]):
        e = moving_bins.tile_entries[i]
        if not box_rejects(moving_bins, e, sx, sy):
            m = entry_moving(geo, e)
            z_range = depth_range(m)
            hidden = all_hidden(occ, row, g, z_range[0])
            if hidden and moving_bins.near_sorted != 0:
                break   # and so is every later entry
            if not hidden and may_show(view, m, z_static):
                z_slots = slots_depth(occ, row, g, whole, m.u0, m.u1, z_range[1])
                if z_slots > -wp.inf and not behind(z_range[0], z_slots):
                    if plane_hidden(m, o, d, z_range, z_slots):
                        wp.atomic_add(skipped, 0, 1)
                    else:
                        n += entry_intervals(view, geo, e, m, o, d, sx, sy, limit, base + n, iv_t, iv_z, iv_e, fallbacks,
                                             occ, row, g, whole)
    return n


@wp.func
def first_candidate(view: View, geo: Geometry, moving_bins: Bins, tile: int, sx: float, sy: float, z_static: float) -> int:
    """The tile-list position of the first moving entry whose swept box and slabs hold the sample
    and that is not wholly behind the static surface (depth z_static), or -1 when there is none
    (moving_intervals is then 0). Coverage itself is left to the fill, which starts there: testing
    it here too (the first entry that covers the sample at some time, as until session 62) cost
    the classify pass more than the few samples it kept out of the fill (rotation's draft
    classify 17 -> 12 ms, `large` 134 -> 105 ms; listed samples 25.2 -> 25.8%, 46.44 -> 46.51%).
    Where the list runs nearest first, the walk stops at the first entry wholly beyond the static
    surface: it and every later one fail may_show (a perspective view's test; list_beyond's margin
    covers the host's and the kernel's depths rounding apart)."""
    stop = view.ortho == 0 and moving_bins.near_sorted != 0
    for i in range(moving_bins.tile_offsets[tile], moving_bins.tile_offsets[tile + 1]):
        e = moving_bins.tile_entries[i]
        if stop and list_beyond(moving_bins, e, z_static):
            return -1
        if not box_rejects(moving_bins, e, sx, sy):
            if may_show(view, entry_moving(geo, e), z_static):
                return i
    return -1


@wp.func
def static_color(view: View, geo: Geometry, sh: Shading, e: int, o: wp.vec3, d: wp.vec3, n_shade_max: int,
                 lights_static: int, bits: int) -> wp.vec4:
    """(rgb, alpha) of a sample that sees only static entry e (or the dome when e < 0): its one
    whole-shutter interval weighted exactly as the resolve weighs it (time slots for bits > 0,
    span lengths for exact), without storing it. Equals resolving the stored interval."""
    if e < 0:
        bg = dome_over(sh, d, 0.0, 1.0)
        return wp.vec4(bg[0], bg[1], bg[2], 0.0)
    m = entry_moving(geo, e)
    n, linear, la, lm, lb = radiance_plan(view, geo, sh, e, m, o, d, 0.0, 1.0, n_shade_max, lights_static)
    color = wp.vec3(0.0, 0.0, 0.0)
    covered = float(0.0)
    r0 = la
    t = wp.vec2(0.0, 1.0)
    for i in range(n):
        s0 = sub_piece_time(t, i, n)
        s1 = sub_piece_time(t, i + 1, n)
        w = s1 - s0
        t_mean = 0.5 * (s0 + s1)
        if bits > 0:
            slots = span_slots(s0, s1, bits)
            w = float(slots[1] - slots[0]) / float(bits)
            t_mean = 0.5 * float(slots[0] + slots[1]) / float(bits)
        if linear != 0:
            r1 = boundary_radiance(view, geo, sh, e, m, o, d, 0.0, 1.0, i + 1, n, la, lm, lb)
            color = color + lerp_in_time(r0, r1, s0, s1, t_mean) * w
            r0 = r1
        else:
            color = color + la * w
        covered = covered + w
    if bits > 0:
        color = color + dome_over(sh, d, 0.0, 1.0) * (1.0 - covered)
    return wp.vec4(color[0], color[1], color[2], covered)


@wp.kernel(enable_backward=False)
def classify_samples(view: View, geo: Geometry, static_bins: Bins, moving_bins: Bins, sub: wp.vec2, direct: int,
                     first_pixel: int,
                     # outputs
                     listed: wp.array(dtype=int), static_hit: wp.array(dtype=int)):
    """static_hit[pix] = the sample's nearest static entry (or -1), reused by the fill pass and
    by shade_static_samples. With direct = 1, a sample no moving entry may reach (first_candidate)
    gets listed 0: shade_static_samples resolves it (static pixels cost what a sharp render costs).
    Other samples get listed = 1 + the tile-list position the fill pass starts from (the entries
    before it have no interval there). No shading here: the frame's shadow maps may still be in the making."""
    pix = first_pixel + wp.tid()
    px = pix % view.width
    py = pix // view.width
    o, d = sample_ray(view, px, py, sub)
    sx = float(px) + sub[0]
    sy = float(py) + sub[1]
    tile = pixel_tile(view, px, py)
    e_static, z_static = nearest_static(view, geo, static_bins, tile, sx, sy, o, d)
    static_hit[pix] = e_static
    first = first_candidate(view, geo, moving_bins, tile, sx, sy, z_static)
    if first < 0 and direct != 0:
        listed[pix] = 0
    elif first < 0:
        listed[pix] = 1 + moving_bins.tile_offsets[tile + 1]
    else:
        listed[pix] = 1 + first


@wp.kernel(enable_backward=False)
def shade_static_samples(view: View, geo: Geometry, sh: Shading, sub: wp.vec2, n_shade_max: int, lights_static: int,
                         bits: int, weight: float, first_pixel: int, listed: wp.array(dtype=int),
                         static_hit: wp.array(dtype=int),
                         # output
                         rgba: wp.array2d(dtype=float)):
    """rgba += weight × the colour of each sample classify_samples listed 0 (it sees only its
    static entry, or the dome): static_color, its one interval weighed as the resolve would."""
    pix = first_pixel + wp.tid()
    if listed[pix] != 0:
        return
    o, d = sample_ray(view, pix % view.width, pix // view.width, sub)
    c = static_color(view, geo, sh, static_hit[pix], o, d, n_shade_max, lights_static, bits)
    add_pixel(rgba, pix, weight, wp.vec3(c[0], c[1], c[2]), c[3])


@wp.kernel(enable_backward=False)
def fill_intervals(view: View, geo: Geometry, moving_bins: Bins, sub: wp.vec2, pixels: wp.array(dtype=int), first: int,
                   spans: wp.array(dtype=wp.vec2i), static_hit: wp.array(dtype=int), listed: wp.array(dtype=int),
                   cull_slots: int, cull_whole: int,
                   # outputs
                   counts: wp.array(dtype=int), fallbacks: wp.array(dtype=int), iv_t: wp.array(dtype=wp.vec2),
                   iv_z: wp.array(dtype=wp.vec2), iv_e: wp.array(dtype=int), occ: wp.array2d(dtype=float),
                   skipped: wp.array(dtype=int)):
    """Listed sample k = first + tid (pixel pixels[k]): counts[k] = its number of intervals (the
    moving entries' first, then its nearest static entry's), stored from spans[k][0] on in the
    chunk's arrays as far as they fit below spans[k][1], leaving out those hidden at every
    culling slot (occlusion.py: cull_slots G, cull_whole for span slots; row tid of occ, shape
    (threads, G + 1), is the sample's scratch; skipped[0] counts the entries plane_hidden skips).
    One pass computes and stores; a sample whose count exceeds its span is filled again with room
    for all (see _IntervalPass)."""
    row = wp.tid()
    k = first + row
    pix = pixels[k]
    base = spans[k][0]
    limit = spans[k][1]
    px = pix % view.width
    py = pix // view.width
    o, d = sample_ray(view, px, py, sub)
    sx = float(px) + sub[0]
    sy = float(py) + sub[1]
    e_static = static_hit[pix]
    z_static = float(wp.inf)
    if e_static >= 0:
        z_static = static_entry_hit(geo, e_static, o, d)[1]
    reset_slots(occ, row, cull_slots, z_static)
    n = moving_intervals(view, geo, moving_bins, pixel_tile(view, px, py), listed[pix] - 1, sx, sy, o, d, z_static,
                         limit, base, iv_t, iv_z, iv_e, fallbacks, occ, row, cull_slots, cull_whole, skipped)
    if e_static >= 0:
        n += entry_intervals(view, geo, e_static, entry_moving(geo, e_static), o, d, sx, sy, limit, base + n, iv_t, iv_z,
                             iv_e, fallbacks, occ, row, cull_slots, cull_whole)
    counts[k] = n
