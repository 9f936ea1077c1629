"""Stochastic rasterization of time-continuous triangles (SPEC §5): N time samples per pixel,
one per stratum [j/N, (j+1)/N), jittered per pixel from a seeded hash: deterministic.

Triangles move as in the analytic method (the same motion segments). For each triangle binned to
the pixel's tile, the time bounds when it can cover the pixel are found from its edge quadratics
(first and last covered instants), and only the samples whose strata meet those bounds are
tested; each sample keeps its nearest hit, then is shaded at its own instant. Static triangles
cover every sample alike, so only the nearest is kept; a pixel where no sample sees a moving
triangle, under still lights, is shaded once with the samples' exact expectation (a moving
shadow averaged over the shutter): static content costs what a sharp render costs. Where samples
do differ (something moves, or fractional opacity samples presence), a still entry under still
lights and shadow maps of one instant is shaded once per pixel and its radiance reused.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from .frame import FrameContext
from .halves import rms
from ..kernels.cutout import cutout_hides, cutout_opacity, has_cutout, opacity_hides
from ..kernels.dome import dome_at, dome_over
from ..kernels.kernel_types import Bins, Geometry, Shading, View
from ..core.parallel import FINE_BANDS, launch_pixels
from ..kernels.raster import add_pixel, box_rejects, list_beyond, pixel_tile
from ..kernels.rays import entry_vertex, intersect_triangle, pixel_ray_direction, pixel_ray_origin, static_entry_hit
from ..kernels.shading import shade_entry_hit, shade_entry_hit_span
from .analytic.coverage import MAX_SPAN_PIECES, entry_edges, next_breakpoint, piece_covered
from .analytic.intervals import nearest_static
from .analytic.segments import prepare_motion

SCRATCH_BYTES = 64 * 2**20
#: tests switch this off to compare against shading still entries at every sample
KEEP_STILL_RADIANCE = True


@wp.func
def covered_time_bounds(view: View, geo: Geometry, e: int, o: wp.vec3, d: wp.vec3) -> wp.vec2:
    """[first, last] shutter time at which moving entry e may cover the ray (empty: lo > hi)."""
    vi = geo.tri_vertices[geo.entry_tri[e]]
    k0 = geo.entry_k0[e]
    k1 = geo.entry_k1[e]
    a0 = geo.positions[k0, vi[0]] - o
    b0 = geo.positions[k0, vi[1]] - o
    c0 = geo.positions[k0, vi[2]] - o
    da = geo.positions[k1, vi[0]] - geo.positions[k0, vi[0]]
    db = geo.positions[k1, vi[1]] - geo.positions[k0, vi[1]]
    dc = geo.positions[k1, vi[2]] - geo.positions[k0, vi[2]]
    ca, cb, cc, ra, rb, rc, dga, dgb, dgc = entry_edges(view, geo, e, d, a0, da, b0, db, c0, dc, vi)
    lo = float(2.0)
    hi = float(-1.0)
    s_prev = float(0.0)
    for _step in range(MAX_SPAN_PIECES):
        if s_prev < 1.0:
            s_next = next_breakpoint(ra, rb, rc, s_prev)
            sm = 0.5 * (s_prev + s_next)
            # bounds must be conservative: a degenerate edge allows both sides here, and the exact
            # per-sample test decides (with the sharp test's tie rule)
            if piece_covered(ca, cb, cc, dga, dgb, dgc, a0, da, b0, db, c0, dc, vi, sm, 1) != 0:
                lo = wp.min(lo, s_prev)
                hi = wp.max(hi, s_next)
            s_prev = s_next
    u0 = float(k0) / float(geo.num_segments)
    u1 = float(k1) / float(geo.num_segments)
    return wp.vec2(u0 + lo * (u1 - u0), u0 + hi * (u1 - u0))


@wp.func
def lower_sample(best_z: wp.array2d(dtype=float), best_e: wp.array2d(dtype=int), tid: int, j: int, n: int, z: float,
                 e: int, unhit: int, far: float):
    """Sample j of row tid now sees entry e at depth z (nearer than what it had): (samples still
    without a hit, the farthest of the samples' hits once every sample has one, else inf)."""
    old = best_z[tid, j]
    best_z[tid, j] = z
    best_e[tid, j] = e
    left = unhit
    if old == wp.inf:
        left = unhit - 1
    if left > 0:
        return left, float(wp.inf)
    farthest = float(far)
    if old >= far:
        # the farthest may have been this sample's (far is inf until every sample has a hit): found again
        farthest = float(-wp.inf)
        for k in range(n):
            farthest = wp.max(farthest, best_z[tid, k])
    return left, farthest


@wp.kernel(enable_backward=False)
def render_stochastic_kernel(view: View, geo: Geometry, sh: Shading, static_bins: Bins, moving_bins: Bins,
                             sub: wp.vec2, n: int, seed: int, lights_static: int, keep_still: int, weight: float,
                             first_pixel: int,
                             # outputs (scratch rows are per band: row = tid)
                             times: wp.array2d(dtype=float), best_z: wp.array2d(dtype=float),
                             best_e: wp.array2d(dtype=int), rgba: wp.array2d(dtype=float),
                             half_diff: wp.array2d(dtype=float)):
    """rgba[pix] += weight × the pixel's mean over its n samples; half_diff[pix] (when it has a
    row per pixel) += weight × (that mean − the mean of its even-indexed samples alone), for the
    frame's error estimate (methods/halves.py); 0 where the pixel is its samples' exact expectation."""
    tid = wp.tid()
    pix = first_pixel + tid
    px = pix % view.width
    py = pix // view.width
    x = float(px) + sub[0]
    y = float(py) + sub[1]
    o = pixel_ray_origin(view, x, y)
    d = pixel_ray_direction(view, x, y)
    state = wp.rand_init(seed, pix)
    for j in range(n):
        times[tid, j] = (float(j) + wp.randf(state)) / float(n)
        best_z[tid, j] = wp.inf
        best_e[tid, j] = -1
    tile = pixel_tile(view, px, py)
    # the nearest static surface covers every sample; moving entries are tracked per sample
    e_static, z_static = nearest_static(view, geo, static_bins, tile, x, y, o, d)
    # the list runs nearest first: the walk stops at the first entry wholly beyond every sample's
    # hit so far (and the static surface); unhit counts the samples with none yet, far is the
    # farthest of their hits once there are none
    unhit = n
    far = float(wp.inf)
    for i in range(moving_bins.tile_offsets[tile], moving_bins.tile_offsets[tile + 1]):
        e = moving_bins.tile_entries[i]
        if moving_bins.near_sorted != 0 and list_beyond(moving_bins, e, wp.min(far, z_static)):
            break
        if box_rejects(moving_bins, e, x, y):
            continue
        still = geo.entry_k0[e] == geo.entry_k1[e]   # a still entry here has fractional opacity
        bounds = wp.vec2(0.0, 1.0)
        if not still:
            bounds = covered_time_bounds(view, geo, e, o, d)
        if bounds[0] <= bounds[1]:
            vi = geo.tri_vertices[geo.entry_tri[e]]
            u0 = float(geo.entry_k0[e]) / float(geo.num_segments)
            u1 = float(geo.entry_k1[e]) / float(geo.num_segments)
            if still:
                u0 = 0.0
                u1 = 1.0
            j0 = wp.clamp(int(wp.floor(bounds[0] * float(n))), 0, n - 1)
            j1 = wp.clamp(int(wp.floor(bounds[1] * float(n))), 0, n - 1)
            if still:
                # the same point at every sample: hit and opacity once, its presence per sample
                tri = geo.entry_tri[e]
                hit = intersect_triangle(o, d, entry_vertex(geo, e, vi[0], 0.0), entry_vertex(geo, e, vi[1], 0.0),
                                         entry_vertex(geo, e, vi[2], 0.0), vi)
                if hit[0] > 0.0 and hit[1] >= view.near and hit[1] <= view.far:
                    tested = has_cutout(geo, tri)
                    opacity = float(1.0)
                    if tested:
                        opacity = cutout_opacity(geo, tri, hit[2], hit[3])
                    for j in range(j0, j1 + 1):
                        u = times[tid, j]
                        if hit[1] < best_z[tid, j] and not (tested and opacity_hides(geo, tri, opacity, u, x, y)):
                            unhit, far = lower_sample(best_z, best_e, tid, j, n, hit[1], e, unhit, far)
            else:
                for j in range(j0, j1 + 1):
                    u = times[tid, j]
                    if u >= u0 and u <= u1:
                        alpha = (u - u0) / (u1 - u0)
                        hit = intersect_triangle(o, d, entry_vertex(geo, e, vi[0], alpha),
                                                 entry_vertex(geo, e, vi[1], alpha), entry_vertex(geo, e, vi[2], alpha),
                                                 vi)
                        if hit[0] > 0.0 and hit[1] >= view.near and hit[1] <= view.far and hit[1] < best_z[tid, j] \
                                and not cutout_hides(geo, geo.entry_tri[e], hit[2], hit[3], u, x, y):
                            unhit, far = lower_sample(best_z, best_e, tid, j, n, hit[1], e, unhit, far)
    moving_seen = int(0)
    for j in range(n):
        if best_e[tid, j] >= 0 and best_z[tid, j] < z_static:
            moving_seen = 1
        else:
            best_e[tid, j] = e_static
    color = wp.vec3(0.0, 0.0, 0.0)
    cover = float(0.0)
    even_color = wp.vec3(0.0, 0.0, 0.0)
    even_cover = float(0.0)
    halves = n > 1 and half_diff.shape[0] > pix
    if moving_seen == 0 and lights_static != 0:
        # every sample sees the same static surface (or nothing) under still lights: the samples'
        # expectation exactly, with a moving shadow averaged over the shutter (one lookup where
        # the shadow never changes), instead of n shadings
        if e_static >= 0:
            color = shade_entry_hit_span(view, geo, sh, e_static, 0.0, 0.5, 1.0, o, d,
                                         static_entry_hit(geo, e_static, o, d))
            cover = 1.0
        else:
            color = dome_over(sh, d, 0.0, 1.0)
    else:
        # a still entry (the static one, or one kept among the moving entries by its fractional
        # opacity) under lights that hold still and shadow maps of one instant (nothing moves in
        # the lights' views) has the same radiance at every sample: shaded once and remembered
        # (two entries; still lights are one knot in the light table, so this equals shading it
        # at every sample exactly)
        keep = keep_still != 0
        kept_e0 = int(-1)
        kept_e1 = int(-1)
        kept_c0 = wp.vec3(0.0, 0.0, 0.0)
        kept_c1 = wp.vec3(0.0, 0.0, 0.0)
        for j in range(n):
            e = best_e[tid, j]
            before = color
            if e >= 0:
                if keep and e == kept_e0:
                    color = color + kept_c0
                elif keep and e == kept_e1:
                    color = color + kept_c1
                else:
                    u = times[tid, j]
                    vi = geo.tri_vertices[geo.entry_tri[e]]
                    alpha = float(0.0)
                    still = geo.entry_k0[e] == geo.entry_k1[e]
                    if not still:
                        u0 = float(geo.entry_k0[e]) / float(geo.num_segments)
                        u1 = float(geo.entry_k1[e]) / float(geo.num_segments)
                        alpha = (u - u0) / (u1 - u0)
                    hit = intersect_triangle(o, d, entry_vertex(geo, e, vi[0], alpha),
                                             entry_vertex(geo, e, vi[1], alpha), entry_vertex(geo, e, vi[2], alpha), vi)
                    radiance = shade_entry_hit(view, geo, sh, e, alpha, u, o, d, hit)
                    if keep and still:
                        if kept_e0 < 0:
                            kept_e0 = e
                            kept_c0 = radiance
                        elif kept_e1 < 0:
                            kept_e1 = e
                            kept_c1 = radiance
                    color = color + radiance
                cover = cover + 1.0
            else:
                color = color + dome_at(sh, d, times[tid, j])
            if j % 2 == 0:
                even_color = even_color + (color - before)
                if e >= 0:
                    even_cover = even_cover + 1.0
        color = color / float(n)
        cover = cover / float(n)
        if halves:
            n_even = float((n + 1) // 2)
            add_pixel(half_diff, pix, weight, color - even_color / n_even, cover - even_cover / n_even)
    add_pixel(rgba, pix, weight, color, cover)


def render_stochastic(ctx: FrameContext) -> np.ndarray:
    s = ctx.settings
    n = s.resolved_samples
    dev = ctx.device
    plan, geo, (static_bins, moving_bins), shading, view = prepare_motion(ctx)
    rgba = wp.zeros((ctx.num_pixels, 4), dtype=float, device=dev)
    # the frame minus its even samples' frame, pixel by pixel (the error estimate; n > 1)
    half_diff = wp.zeros((ctx.num_pixels if n > 1 else 1, 4), dtype=float, device=dev)
    sh = shading()
    sh.shadow_nearest = 1
    subs = ctx.sub_pixel_offsets()
    max_band = max(1, SCRATCH_BYTES // (12 * n))
    lights_static = 1 if plan.lights_static else 0
    # still entries keep their radiance where it is the same at every sample (see the kernel)
    keep_still = 1 if KEEP_STILL_RADIANCE and plan.lights_static and sh.shadow_times <= 1 else 0
    for si, sub in enumerate(subs):
        sub_v = wp.vec2(*sub)
        seed = (s.resolved_seed * 7919 + si * 104729) & 0x7FFFFFFF

        def inputs(first: int, count: int) -> list:
            return [view, geo, sh, static_bins, moving_bins, sub_v, n, seed, lights_static, keep_still, 1.0 / len(subs),
                    first,
                    wp.empty((count, n), dtype=float, device=dev), wp.empty((count, n), dtype=float, device=dev),
                    wp.empty((count, n), dtype=int, device=dev), rgba, half_diff]

        with ctx.timed("render"):
            launch_pixels(render_stochastic_kernel, ctx.num_pixels, inputs, dev, s.threads, max_band=max_band,
                          bands_per_thread=FINE_BANDS)
    ctx.counters.update({"samples_per_pixel": n, "seed": s.resolved_seed,
                         "stochastic_still_radiance_kept": bool(keep_still),
                         "motion_segments": plan.segments_per_prim, "entries": int(len(plan.entry_tri)),
                         "error_estimate": rms(half_diff.numpy()) if n > 1 else None})
    return rgba.numpy()
