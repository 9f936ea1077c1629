"""Analytic motion blur (SPEC §5): extruded-triangle prisms -> per-pixel time intervals with depth
-> front-to-back sort with splitting -> temporal-visibility bitmask (or exact) resolve.

Pipeline per frame: motion segments per prim (segments.py) -> tile bins, static and moving entries
apart -> classify pass (intervals.py; a sample no moving entry reaches is set aside, to be
resolved like a sharp render once shading is ready) -> fill pass over the other samples, which
computes and stores their intervals (coverage and depth, no shading) in one go, nearest entries
first, leaving out what nearer intervals already hide at every time slot (occlusion.py)
(FIRST_FILL_ROOM each; a sample that had more is filled again with room for all, so nothing is
dropped; pixel chunks keep the arrays within the memory budget) -> resolve (resolve.py), which
shades only the intervals it finds visible (radiance.py). Classify and fill need no shading: the
frame's shadow maps are built beside them (segments.start_shading), and the resolves wait for
them.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ..frame import FrameContext
from ..halves import rms
from ...core.parallel import BandCounter, launch_pixels
from .intervals import classify_samples, fill_intervals, shade_static_samples
from .occlusion import CULL_ROW_BYTES_BUDGET, MAX_INSTANT_CULL_SLOTS
from .resolve import resolve_bitmask, resolve_exact
from .segments import prepare_motion

BYTES_PER_INTERVAL = 8 + 8 + 4 + 4  # times, depths, entry, sort index
MAX_EXACT_EVENTS = 1 << 16
# Intervals of room per listed sample in the first fill (and the pilot's); a sample that needs
# more is filled again with exact room. With at least PILOT_MIN listed samples, one run of
# PILOT_BLOCK in every PILOT_STRIDE (pilot_mask) goes first and sets the room of the rest (up to
# MAX_FILL_ROOM).
FIRST_FILL_ROOM = 64
PILOT_MIN = 4096
PILOT_STRIDE = 16
PILOT_BLOCK = 16
MAX_FILL_ROOM = 256
# Occlusion culling in the fill pass (occlusion.py); tests switch it off to compare against
# storing every interval.
OCCLUSION_CULLING = True
# Span slots the fill pass culls with (occlusion.py); 16 measured fastest on the bench scenes
# (session 28: fill 0.50 -> 0.41 s on deep_overlap, 0.22 -> 0.16 s on rotation against the
# resolve's 128 instants, the same intervals shaded), CULL_AT_INSTANTS the alternative.
CULL_SLOTS = 16
CULL_AT_INSTANTS = False
# up to this many time bits (`--time-bits 32`, the draft's until session 53) the resolve's own
# instants are the culling slots: a slot row that short costs little, and short intervals (small
# triangles passing) fill instants where they never cover a whole span slot (session 50: large
# draft 1.99 -> 1.65 s, crossing, rotation, deep_overlap -7 to -12%, near_plane even, demo +4%;
# at 128 bits instants cost more; at 64, the draft's since session 53, large -4%, deep_overlap +4%,
# near_plane +13%)
INSTANT_CULL_BITS = 32
# Samples that no moving entry reaches are resolved without storing intervals (shade_static_samples,
# with the resolve's own weights; tests switch this off to compare against resolving stored intervals).
DIRECT_STATIC_PIXELS = True
#: tests switch this off to compare against shading every interval of a still entry
KEEP_STILL_RADIANCE = True
#: an interval meeting the one shaded before it at a motion-segment junction of the same triangle
#: takes its radiance there (resolve_bitmask); tests switch this off to compare against shading
#: every interval's ends
SEGMENT_JUNCTIONS = True
#: tests switch this off to compare against shading both smooth neighbours where a ray crosses their shared edge
SHARED_EDGES = True
# Time slots per shutter at which exact mode tests a moving cutout (with time bits, the bits'
# own slots): a cutout's mask is point-sampled in time, its edges in space stay exact.
EXACT_CUTOUT_SLOTS = 256


def cull_slots(bits: int) -> tuple[int, int]:
    """(G, whole) culling slots for a resolve of `bits` time bits (0: exact); G = 0 when off.
    Up to INSTANT_CULL_BITS bits the resolve's own instants, else CULL_SLOTS span slots; with
    CULL_AT_INSTANTS, up to MAX_INSTANT_CULL_SLOTS bits use the instants too (they cull more, but
    at 128 keeping them costs more than it saves: culling's cost grows with its slots)."""
    if not OCCLUSION_CULLING:
        return 0, 0
    if 0 < bits <= INSTANT_CULL_BITS or (CULL_AT_INSTANTS and 0 < bits <= MAX_INSTANT_CULL_SLOTS):
        return bits, 0
    return CULL_SLOTS, 1


def pilot_mask(count: int) -> np.ndarray:
    """(count,) bool: the listed samples the pilot fills first, one run of PILOT_BLOCK in every
    PILOT_STRIDE runs: neighbours share their tile lists in cache, where every PILOT_STRIDE-th
    sample alone did not (session 63, frames alternated in one process: deep_overlap's draft
    0.1226 -> 0.1192 s, rotation's 0.0919 -> 0.0909, `large` 1.427 -> 1.404 s). Runs of 64 sampled
    the tail of the interval counts too coarsely: rotation's room fell from 24 to 16 and 740
    samples were filled twice instead of 6; runs of 16 keep the room the scattered pilot chose
    on rotation and deep_overlap (`large`: 48 against 40, 496 -> 11 refilled)."""
    return (np.arange(count) // PILOT_BLOCK) % PILOT_STRIDE == 0


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


class _IntervalPass:
    """Fill and resolve listed samples of one sub-pixel position, chunk by chunk (arrays sized to
    each chunk's room), and keep the interval statistics. Resolves wait (their arrays kept) until
    the pass ends or the memory budget needs their room: the fills, which need no shading, run
    while the frame's shadow maps are still being built (segments.start_shading)."""

    def __init__(self, ctx: FrameContext, view, geo, shading, moving_bins, sub: wp.vec2, n_shade: int,
                 lights_static: int, static_hit: wp.array, listed: wp.array, rgba: wp.array, half_diff: wp.array,
                 weight: float, fallbacks: BandCounter, truncated: BandCounter, shaded: BandCounter,
                 reused: BandCounter, skipped: BandCounter, budget: int) -> None:
        self.ctx, self.view, self.geo, self.shading, self.moving_bins = ctx, view, geo, shading, moving_bins
        self.sub, self.n_shade, self.lights_static = sub, n_shade, lights_static
        self.static_hit, self.listed, self.rgba, self.weight = static_hit, listed, rgba, weight
        self.half_diff = half_diff   # the frame minus its even time slots' frame (resolve_bitmask)
        self.fallbacks, self.truncated, self.shaded, self.reused = fallbacks, truncated, shaded, reused
        self.skipped = skipped
        self.total, self.max, self.peak_bytes, self.chunks, self.refilled = 0, 0, 0, 0, 0
        self.room = FIRST_FILL_ROOM
        self.budget = budget
        self._waiting: list[tuple[np.ndarray, np.ndarray, tuple]] = []   # resolves not run yet
        self._waiting_intervals = 0

    def fill(self, pixels_np: np.ndarray, spans_np: np.ndarray, count_stats: bool):
        """Run the fill pass for samples pixels_np with (start, end) room spans_np: (counts, arrays);
        count_stats False (a refill, which repeats its samples' walks) leaves the pass's near/far and
        skip counts as they are."""
        ctx, dev = self.ctx, self.ctx.device
        n_iv = max(int(spans_np[:, 1].max()) if len(spans_np) else 0, 1)
        if self._waiting and self._waiting_intervals + n_iv > self.budget:
            self.flush()
        self.peak_bytes = max(self.peak_bytes, (self._waiting_intervals + n_iv) * BYTES_PER_INTERVAL)
        self.chunks += 1
        arrays = (wp.empty(n_iv, dtype=wp.vec2, device=dev), wp.empty(n_iv, dtype=wp.vec2, device=dev),
                  wp.empty(n_iv, dtype=int, device=dev))
        pixels = wp.array(pixels_np, dtype=int, device=dev)
        spans = wp.array(spans_np, dtype=wp.vec2i, device=dev)
        counts = wp.zeros(len(pixels_np), dtype=int, device=dev)
        fallbacks = self.fallbacks if count_stats else BandCounter(dev)
        skipped = self.skipped if count_stats else BandCounter(dev)
        g, whole = cull_slots(ctx.settings.resolved_time_bits)
        max_band = max(1, CULL_ROW_BYTES_BUDGET // (4 * (g + 2)))
        with ctx.timed("fill"):
            launch_pixels(fill_intervals, len(pixels_np),
                          lambda first, n: [self.view, self.geo, self.moving_bins, self.sub, pixels, first, spans,
                                            self.static_hit, self.listed, g, whole, counts, fallbacks.band(), *arrays,
                                            wp.empty((n, g + 2), dtype=float, device=dev), skipped.band()],
                          dev, ctx.settings.threads, max_band=max_band)
        return counts.numpy(), arrays

    def resolve(self, pixels_np: np.ndarray, spans_np: np.ndarray, arrays) -> None:
        """Resolve samples pixels_np whose intervals are spans_np of `arrays` into rgba, once the
        pass ends or the budget needs the room (flush)."""
        if len(pixels_np) == 0:
            return
        self._waiting.append((pixels_np, spans_np, arrays))
        self._waiting_intervals += arrays[0].shape[0]

    def flush(self) -> None:
        """Run the waiting resolves, in the order they came, and free their arrays."""
        waiting, self._waiting, self._waiting_intervals = self._waiting, [], 0
        for pixels_np, spans_np, arrays in waiting:
            self._resolve_now(pixels_np, spans_np, arrays)

    def _resolve_now(self, pixels_np: np.ndarray, spans_np: np.ndarray, arrays) -> None:
        ctx, dev, s = self.ctx, self.ctx.device, self.ctx.settings
        bits = s.resolved_time_bits
        words = max((bits + 31) // 32, 1)
        iv_t, iv_z, iv_e = arrays
        shading = (self.view, self.geo, self.shading(), self.sub, self.n_shade, self.lights_static)
        pixels = wp.array(pixels_np.astype(np.int32), dtype=int, device=dev)
        spans = wp.array(spans_np.astype(np.int32), dtype=wp.vec2i, device=dev)
        # still entries shaded once a sample where their radiance is the same at every time
        keep_still = 1 if KEEP_STILL_RADIANCE and self.lights_static and shading[2].shadow_times <= 1 else 0
        with ctx.timed("resolve"):
            if bits > 0:
                order = wp.empty(iv_t.shape[0], dtype=int, device=dev)
                launch_pixels(resolve_bitmask, len(pixels_np),
                              lambda first, n: [*shading, pixels, spans, iv_t, iv_z, iv_e, bits, keep_still,
                                                int(SEGMENT_JUNCTIONS) | 2 * int(SHARED_EDGES), self.weight, first, first,
                                                order,
                                                wp.zeros((n, 3 * words), dtype=wp.uint32, device=dev),
                                                self.shaded.band(), self.reused.band(), self.rgba,
                                                self.half_diff],
                              dev, s.threads)
            else:
                launch_pixels(resolve_exact, len(pixels_np),
                              lambda first, _n: [*shading, pixels, spans, iv_t, iv_z, iv_e, self.weight,
                                                 first, MAX_EXACT_EVENTS, self.truncated.band(), self.shaded.band(),
                                                 self.rgba], dev, s.threads)

    def run(self, pixels_np: np.ndarray, budget: int) -> None:
        """Fill and resolve the listed samples. Many samples: a pilot (pilot_mask: 1/PILOT_STRIDE of
        them) goes first with FIRST_FILL_ROOM each, and the room for the rest is what 99.5% of the pilot's
        samples needed (rounded up to 8, at most MAX_FILL_ROOM): few refills, little memory."""
        if len(pixels_np) < PILOT_MIN:
            self._fill_resolve(pixels_np, budget, FIRST_FILL_ROOM)
        else:
            pilot = pilot_mask(len(pixels_np))
            counts = self._fill_resolve(pixels_np[pilot], budget, FIRST_FILL_ROOM)
            room = int(min(max(8 * np.ceil(np.percentile(counts, 99.5) / 8.0), 8), MAX_FILL_ROOM))
            self.room = room
            self._fill_resolve(pixels_np[~pilot], budget, room)
        self.flush()

    def _fill_resolve(self, pixels_np: np.ndarray, budget: int, room: int) -> np.ndarray:
        """Fill with `room` intervals each, resolve, refill (exactly) those that had more; the
        samples' interval counts."""
        room = max(1, min(room, budget))
        per_chunk = max(1, budget // room)
        all_counts = []
        for c0 in range(0, len(pixels_np), per_chunk):
            chunk = pixels_np[c0:c0 + per_chunk]
            starts = np.arange(len(chunk), dtype=np.int64) * room
            counts, arrays = self.fill(chunk, np.stack([starts, starts + room], axis=1).astype(np.int32), True)
            all_counts.append(counts)
            self.total += int(counts.sum())
            self.max = max(self.max, int(counts.max()))
            fits = counts <= room
            self.resolve(chunk[fits], np.stack([starts[fits], starts[fits] + counts[fits]], axis=1), arrays)
            del arrays
            over, over_counts = chunk[~fits], counts[~fits]
            self.refilled += len(over)
            offsets = np.concatenate([[0], np.cumsum(over_counts, dtype=np.int64)])
            for p0, p1 in pixel_chunks(offsets, budget):
                spans = np.stack([offsets[p0:p1], offsets[p0 + 1:p1 + 1]], axis=1) - offsets[p0]
                refill_counts, arrays = self.fill(over[p0:p1], spans.astype(np.int32), False)
                assert np.array_equal(refill_counts, over_counts[p0:p1]), "refill counted differently"
                self.resolve(over[p0:p1], spans, arrays)
                del arrays
        return np.concatenate(all_counts) if all_counts else np.zeros(0, np.int32)


def render_analytic(ctx: FrameContext) -> np.ndarray:
    s = ctx.settings
    bits = s.resolved_time_bits
    n_shade = s.resolved_samples
    dev = ctx.device
    plan, geo, (static_bins, moving_bins), shading, view = prepare_motion(ctx)
    geo.cutout_slots = bits if bits > 0 else EXACT_CUTOUT_SLOTS
    geo.clip_bits = bits
    num_px = ctx.num_pixels
    rgba = wp.zeros((num_px, 4), dtype=float, device=dev)
    # the frame minus its even time slots' frame, pixel by pixel (the error estimate; bitmask only)
    half_diff = wp.zeros((num_px if bits > 0 else 1, 4), dtype=float, device=dev)
    fallbacks, truncated, shaded, reused, skipped = (BandCounter(dev), BandCounter(dev), BandCounter(dev),
                                                     BandCounter(dev), BandCounter(dev))
    # int32 interval indices: chunks stay below 2**30 intervals
    budget = min(int(s.memory_budget_mb * 2**20 // BYTES_PER_INTERVAL), 2**30)
    subs = ctx.sub_pixel_offsets()
    weight = 1.0 / len(subs)
    lights_static = 1 if plan.lights_static else 0
    direct = 1 if DIRECT_STATIC_PIXELS else 0
    listed_total = 0
    passes = []
    for sub in subs:
        sub_v = wp.vec2(*sub)
        listed = wp.zeros(num_px, dtype=int, device=dev)
        static_hit = wp.zeros(num_px, dtype=int, device=dev)
        with ctx.timed("classify"):
            launch_pixels(classify_samples, num_px,
                          lambda first, _n: [view, geo, static_bins, moving_bins, sub_v, direct, first, listed,
                                             static_hit], dev, s.threads)
        pixels_np = np.nonzero(listed.numpy())[0].astype(np.int32)
        listed_total += len(pixels_np)
        interval_pass = _IntervalPass(ctx, view, geo, shading, moving_bins, sub_v, n_shade, lights_static, static_hit,
                                      listed, rgba, half_diff, weight, fallbacks, truncated, shaded, reused, skipped,
                                      budget)
        interval_pass.run(pixels_np, budget)
        passes.append(interval_pass)
        if direct and len(pixels_np) < num_px:
            # the samples classify_samples left to a sharp render's cost, now that shading is ready
            with ctx.timed("classify"):
                launch_pixels(shade_static_samples, num_px,
                              lambda first, _n: [view, geo, shading(), sub_v, n_shade, lights_static, bits, weight,
                                                 first, listed, static_hit, rgba], dev, s.threads)
    shading()   # joined before the frame ends, even where nothing was shaded with it
    samples_total = max(num_px * len(subs), 1)
    total_iv = sum(p.total for p in passes)
    ctx.counters.update({
        "time_bits": bits, "shading_samples_max": n_shade, "motion_segments": plan.segments_per_prim,
        "light_segments": plan.light_segments,
        "motion_segment_error_px": plan.max_error_px, "motion_snapshots": plan.snapshots, "motion_segments_capped": plan.capped, "entries": int(len(plan.entry_tri)),
        "intervals": total_iv, "intervals_per_pixel_mean": total_iv / samples_total,
        "intervals_per_pixel_max": max(p.max for p in passes), "interval_bytes_peak": max(p.peak_bytes for p in passes),
        "interval_chunks": sum(p.chunks for p in passes), "pixels_with_motion": listed_total / samples_total,
        "pixels_refilled": sum(p.refilled for p in passes) / samples_total,
        "interval_room": max(p.room for p in passes),
        "intervals_shaded": shaded.total(), "junction_ends_reused": reused.total(),
        "near_far_fallbacks": fallbacks.total(), "exact_truncations": truncated.total(),
        "entries_skipped_by_depth": skipped.total(),
        "error_estimate": rms(half_diff.numpy()) if bits > 0 else None,
    })
    return rgba.numpy()
