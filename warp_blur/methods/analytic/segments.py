"""Motion segments: each prim's motion over the shutter as piecewise-linear camera-space paths.

Vertices follow USD's true paths (rotations are arcs). Each prim gets the fewest segments K (a
power of two up to M = max_segments) such that no vertex is more than `error_px` pixels on screen
from where USD puts it at the segments' midpoints (where a chord is farthest from an arc), nor
more than `time_error` × its own screen path length (an edge that moves slowly on screen turns a
small position error into a large error in the time it covers a pixel: this keeps coverage-time
errors near `time_error`), and at least motion:nonlinearSampleCount - 1 segments when its motion
is not linear. A prim that does not move (in camera space) gets one static entry and no prism
work. The lights count as one more unit: their tables (radiance, transform, size) are read
linearly between the kept knots, so they get the fewest segments that keep every light within
1e-3 of its own curve (a light that holds still costs nothing).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Callable

import numpy as np
from pxr import UsdGeom

from ...core.camera import Projection
from ...core.memory import check_entries_fit
from ...core.parallel import Background, default_threads
from ...core.rows import all_corners, same_rows
from ...raster.culling import hidden_back_faces
from .chords import raise_chord_errors, screen_path_px, straddle_knots
from ..frame import MOTION_PROBES
from ...core.log import warn_once
from ...usd.scene import Scene

if TYPE_CHECKING:
    import warp as wp

    from ...kernels.kernel_types import Shading


@dataclass
class MotionPlan:
    """Knots kept for the frame and the entries (triangle, knot span) to render.

    positions: (K+1, V, 3) float64 camera space at u = k/K (a curving path's knots moved so its
    chords straddle it: chords.straddle_knots); normals likewise (or None: USD's own at the knots);
    lights: (K+1, NL, LIGHT_WIDTH); entry_*: (E,) int32; segments_per_prim: path -> K_p (0 = static);
    light_segments: the segments the lights' own curves need (0 = lights hold still).
    """

    positions: np.ndarray
    normals: np.ndarray | None
    lights: np.ndarray
    entry_tri: np.ndarray
    entry_k0: np.ndarray
    entry_k1: np.ndarray
    segments_per_prim: dict
    max_error_px: float
    lights_static: bool
    snapshots: int = 0
    capped: list = None
    tri_visible: np.ndarray | None = None   # (K+1, T) bool at the knots
    light_segments: int = 0

    def sample(self, u: float):
        """The planned scene at shutter time u (positions and lights linear between knots) as a
        shadows.layout.Sample."""
        from ...shadows.layout import Sample
        k_max = self.num_segments
        x = min(max(u, 0.0), 1.0) * k_max
        k = min(int(x), k_max - 1) if k_max > 0 else 0
        f = x - k
        if k_max == 0:
            return Sample(self.positions[0], self.tri_visible[0], self.lights[0])
        pos = self.positions[k] + f * (self.positions[k + 1] - self.positions[k])
        lights = self.lights[k] + np.float32(f) * (self.lights[k + 1] - self.lights[k])
        return Sample(pos, self.tri_visible[k + 1] if f >= 1.0 else self.tri_visible[k], lights)

    def knots(self):
        """The plan at each of its knots, as shadows.layout.Samples: sample() is linear between
        consecutive ones."""
        from ...shadows.layout import Sample
        return [Sample(self.positions[k], self.tri_visible[k], self.lights[min(k, len(self.lights) - 1)])
                for k in range(len(self.positions))]

    @property
    def num_segments(self) -> int:
        return self.positions.shape[0] - 1


# Light table column groups (lights.py) that must follow the knots linearly, each within
# LIGHT_TOLERANCE of its own size: radiance, position, the three axes, radius.
LIGHT_GROUPS = ((1, 4), (4, 7), (7, 10), (10, 13), (13, 16), (16, 17))
LIGHT_TOLERANCE = 1.0e-3
MAX_LIGHT_SEGMENTS = 32   # a light that switches (visibility, a held value) is never linear


def light_deviation(truth: np.ndarray, approx: np.ndarray) -> float:
    """Largest relative deviation of light tables approx from truth ((NL, LIGHT_WIDTH) each): per
    light and column group, |truth - approx| over the larger of their sizes."""
    worst = 0.0
    for c0, c1 in LIGHT_GROUPS:
        a, b = truth[:, c0:c1].astype(np.float64), approx[:, c0:c1].astype(np.float64)
        size = np.maximum(np.linalg.norm(a, axis=1), np.linalg.norm(b, axis=1))
        err = np.linalg.norm(a - b, axis=1)
        rel = np.where(size > 0.0, err / np.maximum(size, 1e-30), 0.0)
        worst = max(worst, float(rel.max()) if len(rel) else 0.0)
    return worst


#: a prim whose chords stray less than this (pixels) at every checked point keeps its knots: the
#: straddle would move them by less than 2/3 of it
STRADDLE_MIN_PX = 1e-4

#: bisection levels up to this many segments are checked at their quarter points, above it at
#: their midpoints (plan_motion)
QUARTER_CHECKED_SEGMENTS = 2


def checks_per_segment(k: int) -> int:
    """Parts a segment of a K-segment level is split into for checking (its inner knots are the
    checked points): 4 (quarter points) up to QUARTER_CHECKED_SEGMENTS segments, else 2."""
    return 4 if k <= QUARTER_CHECKED_SEGMENTS else 2


def _hint(prim) -> int:
    try:
        return int(UsdGeom.MotionAPI(prim).ComputeNonlinearSampleCount())
    except Exception:
        return 3


def plan_entries(tri_unit: np.ndarray, tri_vertices: np.ndarray, seg_of_unit: np.ndarray, k_global: int,
                 vis: np.ndarray, vertex_static: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The frame's entries (triangle, first knot, last knot), int32 each, in unit order: a unit's
    triangles whose vertices never move (or all of them, in a unit with no segments) as static
    entries (k0 = k1 = 0) where visible at the first knot, then its K segments, segment by
    segment, each triangle where visible at the segment's start. tri_unit (T,), tri_vertices
    (T, 3), seg_of_unit (U,) K per unit, vis (knots, T) bool, vertex_static (V,) bool or None."""
    tris = np.arange(len(tri_unit), dtype=np.int64)
    k_of = seg_of_unit[tri_unit] if len(tri_unit) else np.zeros(0, np.int64)
    still = np.zeros(len(tris), bool) if vertex_static is None else all_corners(vertex_static, tri_vertices)
    fixed = (k_of == 0) | still
    fixed_t = tris[fixed & vis[0]]
    moving_t = tris[~fixed]
    reps = k_of[moving_t]
    seg_t = np.repeat(moving_t, reps)
    seg = np.arange(len(seg_t)) - np.repeat(np.cumsum(reps) - reps, reps)   # 0 .. K - 1 within each
    step = k_global // np.maximum(reps, 1)
    a = seg * np.repeat(step, reps)
    b = a + np.repeat(step, reps)
    shown = vis[a, seg_t]
    seg_t, seg, a, b = seg_t[shown], seg[shown], a[shown], b[shown]
    tri = np.concatenate([fixed_t, seg_t])
    part = np.concatenate([np.zeros(len(fixed_t), np.int64), 1 + seg])   # static first, then segment order
    order = np.lexsort((tri, part, tri_unit[tri])) if len(tri) else np.zeros(0, np.int64)
    k0 = np.concatenate([np.zeros(len(fixed_t), np.int64), a])
    k1 = np.concatenate([np.zeros(len(fixed_t), np.int64), b])
    return tri[order].astype(np.int32), k0[order].astype(np.int32), k1[order].astype(np.int32)


def plan_motion(scene: Scene, proj: Projection, shutter_time, max_segments: int = 128,
                error_px: float = 0.25, time_error: float = 0.001, known: dict | None = None) -> MotionPlan:
    """Choose segments per prim by bisection of the shutter. shutter_time(u) -> USD time.

    Snapshots are taken lazily. One and two segments are checked against the true positions at
    their quarter points (the knots of 4K: a wobble whose chord meets the path mid-segment is seen
    there), more segments at their midpoints (the knots of 2K, where a chord is farthest from a
    smooth path; the quarter points cost twice the snapshots and decided no prim differently on the
    bench scenes), so a frame costs about 2·K_max + 1 snapshots (a few more probes decide which
    prims move at all; without the extra probes a prim turning a full circle per half shutter would
    look still). `known` maps shutter fractions to snapshots already taken (the static-frame
    probes), reused where a knot falls on one."""
    instant = shutter_time(0.0) == shutter_time(1.0)
    m = 2 if instant else max(max_segments, 2)
    snaps: dict = {}

    def snap(k: int):
        if k not in snaps:
            reuse = (known or {}).get(k / m)
            snaps[k] = reuse if reuse is not None else scene.snapshot(shutter_time(k / m), with_normals=False)
        return snaps[k]   # (normals: kept knots only, computed below)

    seg_of_unit = [0] * len(scene.units)
    unit_error = [0.0] * len(scene.units)   # each planned prim's chord error at its checks (px)
    pending: dict[int, np.ndarray] = {}
    probes = sorted({int(round(u * m)) for u in MOTION_PROBES}) if not instant else [0]
    moves = np.zeros(len(scene.units), bool)
    if not instant and len(scene.units):   # which prims move at the probes: one pass over all vertices
        first = snap(probes[0]).positions
        moved = np.zeros(len(first), bool)
        for k in probes[1:]:
            moved |= ~same_rows(snap(k).positions, first)
        starts = np.asarray(scene.unit_vertex_offsets[:len(scene.units)], np.int64)
        ends = starts + np.array([u.num_points * u.num_instances for u in scene.units], np.int64)
        counts = np.concatenate([[0], np.cumsum(moved)])
        moves = counts[ends] > counts[starts]
    if moves.any():   # each moving vertex's tolerance: a share of its screen path over the probes
        path_px = screen_path_px(proj, [snap(k).positions for k in probes])
        tolerance = np.maximum(np.minimum(error_px, time_error * path_px), 1e-3)
        for ui in np.flatnonzero(moves):
            o, n = scene.unit_vertex_offsets[ui], scene.units[ui].num_points * scene.units[ui].num_instances
            pending[int(ui)] = tolerance[o:o + n]
    # the lights (intensity, colour, transform) are a unit too: their table is read linearly
    # between the kept knots, so it needs as many segments as its own curve does
    light_k = 0
    lights_pending = not instant and any(not np.array_equal(snap(probes[0]).lights, snap(k).lights)
                                         for k in probes[1:])
    max_err = 0.0
    k = 1
    while (pending or (lights_pending and k <= MAX_LIGHT_SEGMENTS)) and checks_per_segment(k) * k <= m:
        parts = checks_per_segment(k)   # each of the K segments is checked at the knots of parts·K
        stride = m // (parts * k)
        if lights_pending and k <= MAX_LIGHT_SEGMENTS:
            dev_l = 0.0
            for j in range(k):
                a, b = parts * j * stride, (parts * j + parts) * stride
                la, lb = snap(a).lights, snap(b).lights
                for q in range(1, parts):
                    dev_l = max(dev_l, light_deviation(snap(a + q * stride).lights, la + (q / parts) * (lb - la)))
            if dev_l <= LIGHT_TOLERANCE:
                light_k, lights_pending = k, False
        # every pending prim's vertices at once (numpy calls per check, not per prim and check)
        units = list(pending)
        spans = [(scene.unit_vertex_offsets[ui], scene.units[ui].num_points * scene.units[ui].num_instances)
                 for ui in units]
        idx = np.concatenate([np.arange(o, o + n) for o, n in spans]) if units else np.zeros(0, np.int64)
        dev_all = np.zeros(len(idx))
        for j in range(k):
            a, b = parts * j * stride, (parts * j + parts) * stride
            for q in range(1, parts):
                raise_chord_errors(proj, snap(a).positions, snap(b).positions, snap(a + q * stride).positions,
                                   q / parts, idx, dev_all)
        start = 0
        for ui, (o, n) in zip(units, spans):
            dev = dev_all[start:start + n]
            start += n
            if (dev <= pending[ui]).all():
                chosen = k
                if chosen > 1:  # not linear: honour the prim's nonlinear sample count hint
                    while chosen < min(_hint(scene.units[ui].prim) - 1, m):
                        chosen *= 2
                seg_of_unit[ui] = chosen
                unit_error[ui] = float(dev.max()) if n else 0.0
                max_err = max(max_err, unit_error[ui])
                del pending[ui]
        k *= 2
    capped = []
    mids: dict = {}
    for ui in pending:  # use all M segments; verify them at their midpoints, and say so if short
        seg_of_unit[ui] = m
        unit = scene.units[ui]
        o, n = scene.unit_vertex_offsets[ui], unit.num_points * unit.num_instances
        dev = np.zeros(n)
        for j in range(m):
            if j not in mids:
                mids[j] = scene.snapshot(shutter_time((j + 0.5) / m), with_normals=False)
            raise_chord_errors(proj, snap(j).positions, snap(j + 1).positions, mids[j].positions, 0.5,
                               np.arange(o, o + n), dev)
        max_err = max(max_err, float(dev.max()) if n else 0.0)
        if (dev <= pending[ui]).all():
            continue
        capped.append(scene.units[ui].path)
        # the vertex furthest over its tolerance: how far its chords stray, and what was allowed
        worst = int(np.argmax(dev / pending[ui]))
        warn_once(f"segments-cap:{scene.units[ui].path}",
                  f"{scene.units[ui].path}: motion needs more than {m} linear segments in this shutter; "
                  f"rendering with {m}, whose chords stray up to {dev[worst]:.2g} px on screen from "
                  f"USD's path where {pending[ui][worst]:.2g} px is allowed (raise max_segments for more "
                  f"accuracy)")
    if lights_pending:
        light_k = min(m, MAX_LIGHT_SEGMENTS)
        warn_once(f"light-segments-cap:{scene.stage.GetRootLayer().identifier}",   # once per stage and scope
                  f"the lights change faster over the shutter than {light_k} linear segments follow within "
                  f"{LIGHT_TOLERANCE:g} (a switch or a held value?); rendering them linear between "
                  f"{light_k + 1} knots")
    k_global = max(seg_of_unit + [light_k, 1])
    stride = m // k_global
    keep = list(range(0, m + 1, stride))
    positions = np.stack([snap(i).positions for i in keep])
    # the chords of a curving path straddle it (chords.straddle_knots): each prim whose segments'
    # midpoints are knots of m (all but those given all m segments), at the true positions there,
    # unless its chords stray less than STRADDLE_MIN_PX anywhere checked (`large`'s 37 k vertices
    # moving in straight lines: 2.5 ms a frame that would move nothing)
    spans_by_k: dict = {}
    for ui, k_u in enumerate(seg_of_unit):
        if 0 < k_u <= m // 2 and unit_error[ui] >= STRADDLE_MIN_PX:
            o, n = scene.unit_vertex_offsets[ui], scene.units[ui].num_points * scene.units[ui].num_instances
            spans_by_k.setdefault(k_u, []).append(np.arange(o, o + n))
    straddle_knots(positions, {k: np.concatenate(v) for k, v in spans_by_k.items()},
                   lambda k_u, j: snap((2 * j + 1) * m // (2 * k_u)).positions)
    normals = None
    if scene.any_smooth:
        normals = np.stack([scene.shading_normals(snap(i).positions, snap(i).time) for i in keep])
    lights = np.stack([snap(i).lights for i in keep])
    lights_static = bool(all(np.array_equal(snaps[i].lights, snaps[0].lights) for i in snaps))
    vis = np.stack([snap(i).tri_visible for i in keep]) if scene.num_triangles else np.zeros((len(keep), 0), bool)
    # vertices that never move over the sampled knots: their triangles are static entries even
    # inside a moving prim (e.g. the resting instances of an instancer, or a skinned body's torso)
    vertex_static = None
    if snaps:
        first = snaps[min(snaps)].positions
        vertex_static = np.ones(len(first), bool)
        for i in sorted(snaps)[1:]:
            vertex_static &= same_rows(snaps[i].positions, first)
    entry_tri, entry_k0, entry_k1 = plan_entries(scene.tri_unit, scene.tri_vertices, np.array(seg_of_unit, np.int64),
                                                 k_global, vis, vertex_static)
    return MotionPlan(positions=positions, normals=normals, lights=lights, entry_tri=entry_tri,
                      entry_k0=entry_k0, entry_k1=entry_k1,
                      segments_per_prim={u.path: k for u, k in zip(scene.units, seg_of_unit)},
                      max_error_px=max_err, lights_static=lights_static, snapshots=len(snaps), capped=capped,
                      tri_visible=vis, light_segments=light_k)


#: tests switch this off to compare coverage from the per-entry edge tables with coverage computed per ray
EDGE_TABLES = True
#: tests switch this off to compare entries read from the corner table with entries gathered from positions
CORNER_TABLES = True


def prepare_motion(ctx):
    """The moving scene of a frame on the device, as the analytic and stochastic methods use it:
    (plan, Geometry, (Bins of the static entries, Bins of the moving entries), shading, View).
    shading() gives the Shading. Where lights cast shadows, its maps are built on a helper thread
    (parallel.Background) from the moment the plan is known, beside the camera's own set-up and
    whatever the caller runs before it first calls shading(), which waits for them."""
    import warp as wp

    from ...raster.device_data import make_bins, make_geometry
    from ...shadows.free_entries import with_shadow_free
    from .coverage import EDGE_TABLE_WIDTH, edge_table
    from .moving import corner_table
    s = ctx.settings
    with ctx.timed("segments"):
        plan = plan_motion(ctx.scene, ctx.proj, ctx.shutter.time, s.max_segments, s.resolved_segment_error_px,
                           s.resolved_segment_time_error, ctx.probe_snapshots)
        shading = start_shading(ctx, plan)
        hidden = hidden_back_faces(plan.positions, ctx.scene.tri_vertices, ctx.scene.tri_object, ctx.scene.tri_closed,
                                   plan.entry_tri, plan.entry_k0, plan.entry_k1, ctx.proj.near, ctx.proj.far,
                                   ctx.proj.orthographic)
        if hidden.any():
            plan.entry_tri, plan.entry_k0, plan.entry_k1 = (a[~hidden] for a in (plan.entry_tri, plan.entry_k0,
                                                                                  plan.entry_k1))
        ctx.counters["back_faces_dropped"] = int(hidden.sum())
    check_entries_fit(s.method, ctx.proj.width, ctx.proj.height, s.spatial_samples, ctx.scene.num_triangles,
                      len(plan.entry_tri), s.frame_memory_limit_mb)
    geo = make_geometry(ctx.tables, plan.positions, plan.normals, plan.entry_tri, plan.entry_k0, plan.entry_k1)
    if EDGE_TABLES and not ctx.proj.orthographic and len(plan.entry_tri):
        # the moving entries' edge quadratics, once an entry rather than once a pixel ray
        geo.entry_edges = wp.zeros((len(plan.entry_tri), EDGE_TABLE_WIDTH), dtype=wp.vec3, device=ctx.device)
        wp.launch(edge_table, dim=len(plan.entry_tri), inputs=[geo.positions, geo.tri_vertices, geo.entry_tri,
                  geo.entry_k0, geo.entry_k1], outputs=[geo.entry_edges], device=ctx.device)
    if CORNER_TABLES and len(plan.entry_tri):
        # each entry's six corners in one row: the fill, classify and resolve read them per pixel
        geo.entry_corners = wp.empty((len(plan.entry_tri), 6), dtype=wp.vec3, device=ctx.device)
        wp.launch(corner_table, dim=len(plan.entry_tri), inputs=[geo.positions, geo.tri_vertices, geo.entry_tri,
                  geo.entry_k0, geo.entry_k1], outputs=[geo.entry_corners], device=ctx.device)
    # fractional opacity changes with time slots, so its entries take the moving path even when still
    static = (plan.entry_k0 == plan.entry_k1) & ~ctx.scene.tri_fractional[plan.entry_tri]
    tile_bins = ctx.bin_groups(plan.positions, plan.entry_tri, plan.entry_k0, plan.entry_k1, [static, ~static],
                               nearest_first=True)
    bins = tuple(make_bins(b, ctx.device) for b in tile_bins)
    shading = with_shadow_free(shading, geo, len(plan.entry_tri), ctx.device, ctx.counters)
    return plan, geo, bins, shading, ctx.view(tile_bins[0])


def start_shading(ctx, plan: MotionPlan) -> Callable[[], tuple[Shading, "wp.array | None"]]:
    """The frame's Shading over the planned shutter and its maps' occupancy table (or None;
    shadows/free_entries.py), as a callable: made here when no light casts a shadow or the render
    is to use one core, else built by a Background job (the maps read only plan.sample, which
    nothing changes)."""
    from ...raster.device_data import make_shading
    from ...shadows.free_entries import occupancy_table
    s = ctx.settings
    options, textures, dome = ctx.shadow_options(), ctx.scene.materials.textures, ctx.dome_frame()
    _ = ctx.tables   # made here, not raced for by the helper and the camera's set-up

    def build() -> tuple[Shading, "wp.array | None"]:
        shadows = None
        maps = ctx.shadow_maps(plan.sample, plan.knots())
        if maps is not None:
            num_times = maps.times_for(s.shadow_times)
            with ctx.timed("shadow_total"):
                shadows = maps.data([(b + 0.5) / num_times for b in range(num_times)], texel_major=True)
        # lights that hold still are one knot: the same at every time, exactly (between equal knots
        # the linear read rounds differently at each time)
        lights = plan.lights[:1] if plan.lights_static else plan.lights
        sh = make_shading(ctx.scene.material_table, lights, ctx.scene.dome, ctx.device, shadows, options,
                          textures, dome)
        # where casters are in the maps, for the entries that no shadow reaches (still beside the
        # camera's passes), as marked while the maps were written where they were
        laid = shadows.texel_major if shadows is not None else None
        blocks = laid.occupancy if laid is not None and laid.occupancy_complete else None
        return sh, occupancy_table(sh, ctx.device, s.threads, blocks)
    # nothing to build beside the camera's work, or one core asked for: no helper thread
    if not ctx.may_cast_shadows() or (s.threads or default_threads()) == 1:
        built = build()
        return lambda: built
    return Background(build, "shadows").result
