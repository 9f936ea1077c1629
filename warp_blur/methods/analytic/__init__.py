"""Analytic motion blur (SPEC §5): extruded-triangle prisms -> per-pixel time intervals with depth
-> front-to-back sort with splitting -> temporal-visibility bitmask (or exact) resolve.

Pipeline per frame: motion segments per prim (segments.py) -> tile bins, static and moving entries
apart -> count pass (intervals.py; a pixel no moving entry reaches is resolved right there, like a
sharp render) -> prefix sum over the other pixels -> fill pass (exact capacity per pixel, nothing
dropped; pixel chunks when the arrays would exceed the memory budget) -> resolve (resolve.py).
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ...frame import FrameContext
from ...parallel import launch_pixels
from .intervals import count_intervals, fill_intervals
from .resolve import resolve_bitmask, resolve_exact
from .segments import prepare_motion

BYTES_PER_INTERVAL = 8 + 8 + 12 + 4  # times, depths, radiance, sort index
MAX_EXACT_EVENTS = 1 << 16
# Samples that no moving entry reaches are resolved in the count pass, with the resolve's own
# weights (tests switch this off to compare against resolving stored intervals).
DIRECT_STATIC_PIXELS = True


def pixel_chunks(offsets: np.ndarray, budget_intervals: int) -> list[tuple[int, int]]:
    """Split pixels into consecutive ranges whose interval totals fit the budget (>= 1 pixel each)."""
    n = len(offsets) - 1
    chunks, p0 = [], 0
    while p0 < n:
        limit = offsets[p0] + max(budget_intervals, 1)
        p1 = int(np.searchsorted(offsets, limit, side="right")) - 1
        p1 = min(max(p1, p0 + 1), n)
        chunks.append((p0, p1))
        p0 = p1
    return chunks


def render_analytic(ctx: FrameContext) -> np.ndarray:
    s = ctx.settings
    bits = s.resolved_time_bits
    n_shade = s.resolved_samples
    dev = ctx.device
    plan, geo, (static_bins, moving_bins), sh, view = prepare_motion(ctx)
    dome = wp.vec3(*[float(x) for x in ctx.scene.dome])
    num_px = ctx.num_pixels
    rgba = wp.zeros((num_px, 4), dtype=float, device=dev)
    fallbacks = wp.zeros(1, dtype=int, device=dev)
    truncated = wp.zeros(1, dtype=int, device=dev)
    dummy2 = wp.zeros(1, dtype=wp.vec2, device=dev)
    dummy3 = wp.zeros(1, dtype=wp.vec3, device=dev)
    words = max((bits + 31) // 32, 1)
    budget = int(s.memory_budget_mb * 2**20 // BYTES_PER_INTERVAL)
    subs = ctx.sub_pixel_offsets()
    weight = 1.0 / len(subs)
    lights_static = 1 if plan.lights_static else 0
    direct = 1 if DIRECT_STATIC_PIXELS else 0
    total_iv, max_iv, peak_bytes, num_chunks, listed = 0, 0, 0, 0, 0
    for sub in subs:
        sub_v = wp.vec2(*sub)
        counts = wp.zeros(num_px, dtype=int, device=dev)
        static_hit = wp.zeros(num_px, dtype=int, device=dev)
        with ctx.timed("count"):
            launch_pixels(count_intervals, num_px,
                          lambda first, _n: [view, geo, sh, static_bins, moving_bins, sub_v, n_shade, lights_static,
                                             direct, bits, weight, first, counts, fallbacks, dummy2, dummy2, dummy3,
                                             static_hit, rgba], dev, s.threads)
        counts_np = counts.numpy()
        # pixels resolved in the count pass (no moving entry reaches them) count 0 and are not listed
        pixels_np = np.nonzero(counts_np)[0].astype(np.int32) if direct else np.arange(num_px, dtype=np.int32)
        listed += len(pixels_np)
        list_counts = counts_np[pixels_np]
        offsets_np = np.concatenate([[0], np.cumsum(list_counts, dtype=np.int64)])
        if offsets_np[-1] >= 2**31:
            # int32 offsets: render in chunks whose local offsets stay small
            budget = min(budget, 2**30)
        total_iv += int(offsets_np[-1])
        max_iv = max(max_iv, int(counts_np.max()) if len(counts_np) else 0)
        chunks = pixel_chunks(offsets_np, budget)
        num_chunks += len(chunks)
        offsets = wp.array(offsets_np.clip(max=2**31 - 1).astype(np.int32), dtype=int, device=dev)
        pixels = wp.array(pixels_np, dtype=int, device=dev)
        for p0, p1 in chunks:
            base = int(offsets_np[p0])
            n_iv = int(offsets_np[p1] - base)
            peak_bytes = max(peak_bytes, n_iv * BYTES_PER_INTERVAL)
            iv_t = wp.zeros(max(n_iv, 1), dtype=wp.vec2, device=dev)
            iv_z = wp.zeros(max(n_iv, 1), dtype=wp.vec2, device=dev)
            iv_rgb = wp.zeros(max(n_iv, 1), dtype=wp.vec3, device=dev)
            order = wp.zeros(max(n_iv, 1), dtype=int, device=dev)
            with ctx.timed("fill"):
                launch_pixels(fill_intervals, p1 - p0,
                              lambda first, _n: [view, geo, sh, moving_bins, sub_v, n_shade, lights_static, pixels,
                                                 first, offsets, base, fallbacks, iv_t, iv_z, iv_rgb, static_hit],
                              dev, s.threads, start=p0)
            with ctx.timed("resolve"):
                if bits > 0:
                    launch_pixels(resolve_bitmask, p1 - p0,
                                  lambda first, n: [view, dome, pixels, offsets, base, iv_t, iv_z, iv_rgb, bits,
                                                    weight, first, first, order,
                                                    wp.zeros((n, 2 * words), dtype=wp.uint32, device=dev), rgba],
                                  dev, s.threads, start=p0)
                else:
                    launch_pixels(resolve_exact, p1 - p0,
                                  lambda first, _n: [view, dome, pixels, offsets, base, iv_t, iv_z, iv_rgb, weight,
                                                     first, MAX_EXACT_EVENTS, truncated, rgba], dev, s.threads,
                                  start=p0)
    samples_total = max(num_px * len(subs), 1)
    ctx.counters.update({
        "time_bits": bits, "shading_samples_max": n_shade, "motion_segments": plan.segments_per_prim,
        "motion_segment_error_px": plan.max_error_px, "motion_snapshots": plan.snapshots, "motion_segments_capped": plan.capped, "entries": int(len(plan.entry_tri)),
        "intervals": total_iv, "intervals_per_pixel_mean": total_iv / samples_total,
        "intervals_per_pixel_max": max_iv, "interval_bytes_peak": peak_bytes, "interval_chunks": num_chunks,
        "pixels_with_motion": listed / samples_total,
        "near_far_fallbacks": int(fallbacks.numpy()[0]), "exact_truncations": int(truncated.numpy()[0]),
    })
    return rgba.numpy()
