"""Accumulation, the reference: N sharp instants at u_i = (i + 0.5)/N, averaged (SPEC §5).

Only the work the scene requires: screen tiles that no moving (or appearing) triangle touches at
any of the N instants see the same surfaces at every instant. Under lights that hold still and
cast no shadow, or whose shadow maps are the same at every instant (nothing moves in the lights'
views), they look the same too, and are rendered once; otherwise their visibility is
found once and only their shading is redone per instant (under lights that hold still, not even
that where every shadow lookup reads texels that never change). The other tiles are rendered at every
instant, but only the triangles that change are rasterised there per instant: the nearest of the
still ones is found once (and shaded once where shading is steady) and shown wherever nothing
that changes is in front of it. Where nothing moves at all and only fractional opacity makes the
instants differ (presence), the moving tiles' instants are one pass that shades each surface a
pixel shows once. The result is the same average (tested against rendering every pixel at every
instant).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Iterator

import numpy as np

from ..core.parallel import run_prepared
from ..core.rows import all_corners, same_rows
from ..kernels.raster import INSTANT_CACHE_SLOTS
from ..raster.binning import SAMPLE_MARGIN_PX, TILE_SIZE, entry_pixel_bounds, tile_mask_pixels
from ..shadows.pairs import may_drop_lights, pair_receivers
from .frame import FrameContext
from .halves import InstantHalves

#: tests switch this off to compare against rendering every pixel at every instant
STATIC_TILES = True
#: tests switch this off to compare against rasterising every triangle in the moving tiles
MOVING_SPLIT = True
#: tests switch this off to compare against reshading every still pixel at every instant
STEADY_PIXELS = True
#: tests switch this off to compare against one pass per instant where only presence changes
INSTANTS_IN_ONE_PASS = True
#: share of the memory budget that every instant's positions may take, kept as the shadow maps'
#: knots (_knots_fit)
KNOT_BUDGET_SHARE = 0.125
#: bytes per recorded hit (triangle index and (hit, depth, barycentrics)), held for the frame
RECORD_BYTES = 4 + 16
#: bytes per recorded radiance and its flag (moving tiles under still lights)
COLOR_BYTES = 13
#: bytes per moving-tile sub-sample of the one-pass instants' remembered radiances (a triangle
#: index and a radiance per slot), held for that pass
PRESENCE_CACHE_BYTES = int(INSTANT_CACHE_SLOTS) * (4 + 12)


def instants(n: int) -> np.ndarray:
    """Shutter fractions of the N accumulation instants."""
    return (np.arange(n) + 0.5) / n


@dataclass
class MovingTiles:
    """pixels: flat indices (ascending) of the pixels in screen tiles that a triangle which moves
    or changes visibility covers (by its screen box) at one of the instants; steady: shading is
    the same at every instant too (lights that hold still and cast no shadow, or whose shadow maps
    are the same at every instant); needed (T,) bool:
    the triangles that can show in those tiles (the moving ones and still ones whose box meets
    a moving tile); changing (T,) bool: the triangles that move, change visibility or have
    fractional opacity (the others look the same at every instant); lights_still: the lights
    are the same at every instant (their shadows may not be); nothing_moves: neither the camera,
    nor a vertex, nor a triangle's visibility, nor a light changes over the instants (they differ
    only in the presence of fractional opacity)."""

    pixels: np.ndarray
    steady: bool
    needed: np.ndarray
    changing: np.ndarray
    lights_still: bool = False
    nothing_moves: bool = False


def moving_tile_pixels(ctx: FrameContext, us: np.ndarray) -> MovingTiles | None:
    """Where the instants `us` differ (see MovingTiles), or None when nothing is still. One sweep:
    at each instant the triangles that differ from the first instant mark their tiles there; the
    ones that moved at some instant also mark their tiles at the first instant (where they are
    whenever they do not differ from it)."""
    scene = ctx.scene
    first = ctx.snapshot(float(us[0]), with_normals=False)
    casts = ctx.may_cast_shadows() and len(first.lights) and (first.lights[:, 17] > 0.5).any()
    # every instant's snapshot, kept when the lights that darken nothing lit could be told from them
    # (shadows/pairs.py: the instants are all the frame shades, so those lights get no maps)
    knots = [first] if casts and _knots_fit(ctx, first, len(us)) else None
    num_tris = scene.num_triangles
    still_v = np.ones(len(first.positions), bool)
    same_vis = np.ones(num_tris, bool)
    proj = ctx.proj
    tiles_x = (proj.width + TILE_SIZE - 1) // TILE_SIZE
    tiles_y = (proj.height + TILE_SIZE - 1) // TILE_SIZE
    marks = np.zeros((tiles_y + 1, tiles_x + 1), np.int64)   # 2D difference array of tile boxes

    def visible(snap) -> np.ndarray:
        return snap.tri_visible if len(snap.tri_visible) == num_tris else np.ones(num_tris, bool)

    def mark(positions: np.ndarray, tris: np.ndarray) -> None:
        tx0, ty0, tx1, ty1 = tile_rects(ctx, positions, tris.astype(np.int32))
        np.add.at(marks, (ty0, tx0), 1)
        np.add.at(marks, (ty0, tx1), -1)
        np.add.at(marks, (ty1, tx0), -1)
        np.add.at(marks, (ty1, tx1), 1)

    lights_still = True
    camera_still = True
    for u in us[1:]:
        snap = ctx.snapshot(float(u), with_normals=False)
        if snap.positions.shape != first.positions.shape:
            return None
        lights_still &= np.array_equal(snap.lights, first.lights)
        camera_still &= np.array_equal(snap.cam_from_world, first.cam_from_world)
        same_v = same_rows(snap.positions, first.positions)
        same_t = visible(snap) == visible(first)
        still_v &= same_v
        same_vis &= same_t
        differ = ~(same_t & all_corners(same_v, scene.tri_vertices))
        mark(snap.positions, np.nonzero(differ & visible(snap))[0])
        if knots is not None:
            knots.append(snap)
    # shadows leave still pixels alike too when every instant shades with the same maps (nothing
    # moves in any light's view: ShadowMaps.static; lights that move are caught below)
    maps = ctx.instant_shadow_maps(knots) if casts else None
    knots = None   # (the maps are made: the instants' copies go back now, not at the frame's end)
    steady = (not casts or maps is None or maps.static) and lights_still
    still = same_vis & all_corners(still_v, scene.tri_vertices) & ~scene.tri_fractional
    if not still.any():
        return None
    mark(first.positions, np.nonzero(~still & visible(first))[0])
    tile_moving = marks.cumsum(axis=0).cumsum(axis=1)[:tiles_y, :tiles_x] > 0
    # still triangles that can show in a moving tile (their box is the same at every instant)
    integral = np.zeros((tiles_y + 1, tiles_x + 1), np.int64)
    integral[1:, 1:] = tile_moving.cumsum(axis=0).cumsum(axis=1)
    still_idx = np.nonzero(still)[0].astype(np.int32)
    tx0, ty0, tx1, ty1, kept = tile_rects(ctx, first.positions, still_idx, with_kept=True)
    touched = (integral[ty1, tx1] - integral[ty0, tx1] - integral[ty1, tx0] + integral[ty0, tx0]) > 0
    needed = ~still
    needed[kept[touched]] = True
    nothing_moves = lights_still and camera_still and still_v.all() and same_vis.all()
    return MovingTiles(tile_mask_pixels(tile_moving, TILE_SIZE, proj.width, proj.height), bool(steady), needed,
                       ~still, bool(lights_still), bool(nothing_moves))


def _knots_fit(ctx: FrameContext, first, n: int) -> bool:
    """Whether n instants' snapshots like `first` are worth keeping as knots for the shadow maps'
    test of lights that darken nothing lit: it can drop a light (no lit surface that may shadow
    itself is seen at the first instant, pairs.may_drop_lights) and they fit in KNOT_BUDGET_SHARE
    of the memory budget."""
    receivers = pair_receivers(ctx.scene)
    if receivers is None or not may_drop_lights(first.tri_visible, *receivers):
        return False
    return n * first.positions.nbytes <= KNOT_BUDGET_SHARE * ctx.settings.memory_budget_mb * 2**20


def tile_rects(ctx: FrameContext, positions: np.ndarray, tris: np.ndarray, with_kept: bool = False):
    """Screen-tile rectangles [tx0, tx1) × [ty0, ty1) of triangles' pixel boxes at camera-space
    positions (V, 3), for the triangles that can be on screen (returned too with with_kept)."""
    proj = ctx.proj
    tiles_x = (proj.width + TILE_SIZE - 1) // TILE_SIZE
    tiles_y = (proj.height + TILE_SIZE - 1) // TILE_SIZE
    k = np.zeros(len(tris), np.int32)
    boxes, keep = entry_pixel_bounds(proj, positions[None], ctx.scene.tri_vertices, tris, k, k, SAMPLE_MARGIN_PX)
    b = boxes[keep]
    rect = (np.clip(np.floor(b[:, 0] / TILE_SIZE), 0, tiles_x - 1).astype(np.int64),
            np.clip(np.floor(b[:, 1] / TILE_SIZE), 0, tiles_y - 1).astype(np.int64),
            np.clip(np.floor(b[:, 2] / TILE_SIZE), 0, tiles_x - 1).astype(np.int64) + 1,
            np.clip(np.floor(b[:, 3] / TILE_SIZE), 0, tiles_y - 1).astype(np.int64) + 1)
    return (*rect, tris[keep]) if with_kept else rect


def render_accumulation(ctx: FrameContext) -> np.ndarray:
    n = ctx.settings.resolved_samples
    if ctx.shutter.instant and not ctx.scene.any_fractional:
        n = 1  # every instant is the same one (fractional opacity still samples presence per instant)
    halves = InstantHalves(ctx.num_pixels, n, ctx.device)
    ctx.instants = n
    us = instants(n)
    plan = moving_tile_pixels(ctx, us) if (STATIC_TILES and n > 1) else None
    split = False
    one_pass = False
    if plan is not None:
        # recorded hits: a triangle index and a vec4 per still pixel and sub-sample (still tiles
        # reshaded per instant), and per moving-tile pixel and sub-sample (with its radiance when
        # steady) where still triangles can show behind the changing ones
        subs = ctx.settings.spatial_samples ** 2
        budget = ctx.settings.memory_budget_mb * 2**20
        still_bytes = 0 if plan.steady else (ctx.num_pixels - len(plan.pixels)) * subs * RECORD_BYTES
        if still_bytes > budget:
            plan = None
        else:
            one_pass = INSTANTS_IN_ONE_PASS and plan.steady and plan.nothing_moves
            moving_bytes = len(plan.pixels) * subs * (RECORD_BYTES + (COLOR_BYTES if plan.lights_still else 0)
                                                      + (PRESENCE_CACHE_BYTES if one_pass else 0))
            split = MOVING_SPLIT and (plan.needed & ~plan.changing).any() and still_bytes + moving_bytes <= budget
    # each pass's host work (snapshot, binning, uploads, shadow maps) is done on a helper thread
    # while the pass before it renders
    recorded: list = []
    # still surfaces under still lights whose shadows move: the maps' varying-texel flags tell
    # which of their pixels never change (built only then: they cost tens of ms of NumPy)
    ctx.instant_flags = plan is not None and STEADY_PIXELS and plan.lights_still and not plan.steady
    run_prepared(_passes(ctx, us, plan, split, split and one_pass, halves, recorded))
    exact = None   # pixels added at full weight: the same at every instant
    if plan is not None and plan.steady:
        exact = np.ones(ctx.num_pixels, bool)   # a mask: np.setdiff1d took ~180 ms at 640×480
        exact[plan.pixels] = False
    done = [h for h in recorded if h is not None and h.done is not None]
    if done:   # the still pixels found to look the same at every instant, shaded once
        flags = done[0].done.numpy()
        ctx.counters["accumulation_steady_pixels"] = float(flags.mean())
        exact = done[0].pixels.numpy()[flags != 0]
    if plan is not None:
        ctx.counters["accumulation_still_pixels"] = 1.0 - len(plan.pixels) / ctx.num_pixels
        ctx.counters["accumulation_still_shading"] = "once" if plan.steady else "per instant"
        ctx.counters["accumulation_moving_tiles"] = "changing triangles" if split else "every triangle"
    ctx.counters["instants"] = n
    # one instant for a shutter of one instant: no time to sample, no error to estimate
    ctx.counters["error_estimate"] = 0.0 if ctx.shutter.instant and n == 1 else halves.estimate(exact)
    return halves.image()


def _passes(ctx: FrameContext, us: np.ndarray, plan: MovingTiles | None, split: bool, one_pass: bool,
            halves: InstantHalves, recorded: list) -> Iterator[Callable[[], None]]:
    """The frame's passes in order, each prepared when asked for (frame.prepare_sharp_pass): with
    a plan, still tiles once (steady) or found once and reshaded per instant, and the moving
    tiles at every instant (with split, the still triangles there found once, and only the
    changing ones rasterised per instant); without one, every pixel at every instant. The still
    tiles' recorded hits are appended to `recorded`. With one_pass (split, nothing moves, steady
    shading) the moving tiles' instants are one pass after the record pass. Instant i's passes add
    into halves.target(i); the passes at full weight into halves.even."""
    n = len(us)
    if plan is None:
        for i, snap in enumerate(_snapshots(ctx, us)):
            run, _ = ctx.prepare_sharp_pass(snap, 1.0 / n, halves.target(i))
            if run is not None:
                yield run
        return
    still = np.ones(ctx.num_pixels, bool)
    still[plan.pixels] = False
    still_px = np.nonzero(still)[0]
    hits = None
    behind = None
    for i, snap in enumerate(_snapshots(ctx, us)):
        run = None
        rgba = halves.target(i)
        if i == 0 and plan.steady:   # still tiles look the same at every instant: once, at full weight
            run, _ = ctx.prepare_sharp_pass(snap, 1.0, halves.even, still_px)
        elif i == 0:                 # still tiles see the same surfaces: find them once, shade per instant
            # (under still lights, a pixel whose shadow lookups never change is shaded once)
            run, hits = ctx.prepare_sharp_pass(snap, 1.0 / n, rgba, still_px, record=True,
                                               whole_if_steady=STEADY_PIXELS and plan.lights_still)
            recorded.append(hits)
        elif hits is not None:
            run = ctx.prepare_reshade_pass(snap, hits, 1.0 / n, rgba)
        if run is not None:
            yield run
        if split:
            if i == 0:   # the still triangles' nearest hit in the moving tiles, once
                keep = 1 if plan.steady else (2 if STEADY_PIXELS and plan.lights_still else 0)
                run, behind = ctx.prepare_record_pass(snap, plan.pixels, plan.needed & ~plan.changing, keep)
                yield run
            if one_pass:
                # only presence differs between the instants: every instant in one pass, each
                # surface a sub-sample shows shaded once
                yield ctx.prepare_over_recorded_pass(snap, behind, plan.changing, 1.0 / n, halves.even, instants=us,
                                                     rgba_odd=halves.odd)
                ctx.counters["accumulation_presence_pass"] = True
                return
            run = ctx.prepare_over_recorded_pass(snap, behind, plan.changing, 1.0 / n, rgba)
        else:
            run, _ = ctx.prepare_sharp_pass(snap, 1.0 / n, rgba, plan.pixels, triangles=plan.needed)
        if run is not None:
            yield run


def _snapshots(ctx: FrameContext, us: np.ndarray):
    """The snapshots at instants us in turn, each taken one step ahead and set as ctx.neighbour
    of the one before (the last instant's neighbour is the one before it), so that shadow
    lookups' receiver velocities need no snapshot of their own."""
    ahead = ctx.snapshot(float(us[0]))
    behind = None
    for i in range(len(us)):
        snap = ahead
        ahead = ctx.snapshot(float(us[i + 1])) if i + 1 < len(us) else None
        ctx.neighbour = ahead if ahead is not None else behind
        yield snap
        behind = snap
    ctx.neighbour = None
