"""What every method shares for one frame: the scene, camera, shutter, device tables, and the
sharp passes (shading an instant; a still frame's Z and motion AOVs from its own pass; the AOVs'
pass of their own is aovs.py's)."""

from __future__ import annotations

import threading
import time
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
import warp as wp

from ..raster.binning import SAMPLE_MARGIN_PX, TILE_SIZE, TileBins, bin_entries, entry_bounds
from ..core.camera import Projection
from ..raster.culling import hidden_back_faces
from ..raster.device_data import TriangleTables, make_bins, make_geometry, make_shading, make_view
from ..kernels.kernel_types import Geometry
from ..core import progress
from ..core.affine import invert_affine
from ..core.parallel import FINE_BANDS, SHARP_WIDEST, launch_pixels
from ..kernels.raster import (INSTANT_CACHE_SLOTS, record_nearest, render_over_recorded,
                              render_over_recorded_instants, render_sharp, render_sharp_depth_motion,
                              shade_recorded)
from ..usd.scene import Scene, Snapshot
from ..core.settings import RenderSettings
from ..shadows.layout import Sample, ShadowOptions
from ..shadows.maps import ShadowMaps, lit_materials
from ..shadows.pairs import pair_receivers
from ..usd.stage import Shutter
from ..usd.textures import texture_lod


#: Shutter fractions probed to decide that nothing moves. Open, centre and close alone alias
#: (a full turn per half shutter looks static); the irregular extra probes make that unlikely.
#: They lie on the motion planner's default grid (k/128), so it reuses these snapshots.
#: camera-to-dome rotations over the shutter for a textured dome (read linearly between them):
#: 16 segments keep a 90° turn within 6° per segment
DOME_KNOTS = 17
MOTION_PROBES = (0.0, 16 / 128, 32 / 128, 64 / 128, 79 / 128, 96 / 128, 1.0)
_TIMINGS_LOCK = threading.Lock()
#: tests switch this off to compare a still frame's Z and motion with those of their own pass
STATIC_AOVS_IN_ONE_PASS = True


@dataclass
class RecordedHits:
    """Per listed pixel (pixels, (P,)) and sub-sample: the triangle seen (-1: none) and its hit
    (1, depth, barycentrics of b and c), and the view, for reshading at other instants."""

    view: object
    pixels: wp.array
    entries: wp.array
    hits: wp.array
    colors: wp.array | None = None   # (P, subsamples) vec3 radiance at the recording instant, when kept
    done: wp.array | None = None     # (P,) uint8: 1 where the pixel was added whole (render_sharp, record 2)
    kept: wp.array | None = None     # (P, subsamples) uint8: 1 where `colors` holds every instant's radiance
    pending: wp.array | None = None  # rows whose done flag is 0, found once the recording has run
    pending_count: int = 0


@dataclass
class FrameContext:
    scene: Scene
    proj: Projection
    shutter: Shutter
    settings: RenderSettings
    device: str
    timings: dict = field(default_factory=dict)
    counters: dict = field(default_factory=dict)
    _tables: TriangleTables | None = None
    aov_motion: np.ndarray | None = None
    aov_depth: np.ndarray | None = None
    _instant_shadows: ShadowMaps | None = None
    _velocities: tuple | None = None   # (snapshot time, (V, 3) velocities) of the last sharp instant
    neighbour: Snapshot | None = None   # an adjacent sharp instant's snapshot (accumulation sets it)
    _shading_last: tuple | None = None   # (time, Shading) of the last instant shaded
    _per_triangle_last: tuple | None = None   # (snapshot, Geometry) of the last per_triangle_geometry
    _occupancy_last: tuple | None = None   # (shadow maps array, occupancy table) of the last instant's maps
    #: sharp instants' Shading carries the maps' varying-texel flags (render_sharp's record = 2 reads them)
    instant_flags: bool = False
    probe_snapshots: dict = field(default_factory=dict)   # shutter fraction -> Snapshot (static_frame's)
    instants: int = 1   # sharp instants this frame will shade (accumulation sets it)
    instant_knots: list | None = None   # snapshots of every scene its instants shade: knots for ShadowMaps

    def release(self) -> None:
        """Drop the frame's caches (shadow maps, the last Shading and geometry, snapshots) once
        the frame is done. The context sits in reference cycles (closures over it), which only
        Python's occasional full collection frees: without this, a frame's buffers outlived it
        and the next frame allocated (and faulted in) its own, e.g. accumulation's 50 MB of
        shadow maps on demo."""
        self._instant_shadows = None
        self._shading_last = None
        self._per_triangle_last = None
        self._occupancy_last = None
        self._velocities = None
        self.neighbour = None
        self.probe_snapshots = {}
        self.instant_knots = None

    @contextmanager
    def timed(self, stage: str):
        progress.stage(stage)
        t0 = time.perf_counter()
        try:
            yield
        finally:
            with _TIMINGS_LOCK:   # helper threads (shadows, AOVs) add to the frame's stages too
                self.timings[stage] = self.timings.get(stage, 0.0) + time.perf_counter() - t0

    @property
    def num_pixels(self) -> int:
        return self.proj.width * self.proj.height

    @property
    def tables(self) -> TriangleTables:
        if self._tables is None:
            s = self.scene
            lod = None
            if s.textured:
                centre = self.probe_snapshots.get(0.5) or self.snapshot(0.5, with_normals=False)
                lod = texture_lod(self.proj, centre.positions, s.tri_vertices, s.corner_uvs)
            self._tables = TriangleTables(s.tri_vertices, s.tri_flags, s.tri_material, s.corner_colors, self.device,
                                          s.corner_uvs if s.textured else None, lod, s.tri_cutout,
                                          s.materials.textures, s.tri_alpha)
        return self._tables

    def snapshot(self, u: float, with_normals: bool = True) -> Snapshot:
        with self.timed("scene"):
            snap = self.scene.snapshot(self.shutter.time(u), with_normals)
        snap.fraction = float(u)
        return snap

    def probed_snapshot(self, u: float, with_normals: bool = True) -> Snapshot:
        """The snapshot at shutter fraction u that static_frame's probes took, if they took it (the
        centre's has normals), else a new one. Shared: replace it (dataclasses.replace) to change it."""
        snap = self.probe_snapshots.get(u)
        if snap is None or (with_normals and u != 0.5):
            return self.snapshot(u, with_normals)
        return snap

    def static_frame(self) -> Snapshot | None:
        """The centre snapshot when nothing changes over the shutter (geometry, visibility, camera
        and lights identical at open, centre and close, no fractional opacity), else None: such a
        frame is one sharp render."""
        if self.scene.any_fractional:   # presence varies over the samples even when nothing moves
            return None
        if self.shutter.instant:
            return self.snapshot(0.5)
        a = self.probe_snapshots[0.5] = self.snapshot(0.5)
        for u in MOTION_PROBES:
            if u == 0.5:
                continue
            b = self.probe_snapshots[u] = self.snapshot(u, with_normals=False)
            if not (np.array_equal(a.positions, b.positions) and np.array_equal(a.tri_visible, b.tri_visible)
                    and np.array_equal(a.lights, b.lights)):
                return None
        return a

    def render_static(self, snapshot: Snapshot, aovs: bool = False) -> np.ndarray:
        """(H*W, 4) sharp image of a frame where nothing moves (every method's exact answer). With
        aovs (pixel centres only: one spatial sample), the Z and motion AOVs (motion 0: nothing
        moves) come from the same visibility pass, kept in aov_depth and aov_motion, instead of a
        pass of their own (aovs.depth_motion)."""
        rgba = wp.zeros((self.num_pixels, 4), dtype=float, device=self.device)
        buffers = None
        if aovs and self.settings.spatial_samples == 1 and STATIC_AOVS_IN_ONE_PASS:
            buffers = (wp.zeros(self.num_pixels, dtype=float, device=self.device),
                       wp.zeros(self.num_pixels, dtype=wp.vec2, device=self.device))
        run, _hits = self.prepare_sharp_pass(snapshot, 1.0, rgba, aov_buffers=buffers)
        if run is not None:
            run()
        if buffers is not None:
            h, w = self.proj.height, self.proj.width
            self.aov_depth = buffers[0].numpy().reshape(h, w).copy()
            self.aov_motion = buffers[1].numpy().reshape(h, w, 2).copy()
        self.counters["static_frame"] = True
        return rgba.numpy()

    # ------------------------------------------------------------------------------ shadows
    def shadow_options(self) -> ShadowOptions:
        s = self.settings
        return ShadowOptions(mode=s.resolved_shadows, size=s.resolved_shadow_map_size, grid=s.shadow_grid,
                             times=s.shadow_times, keys=s.shadow_keys, light_samples=s.resolved_light_samples,
                             bias=s.shadow_bias, normal_bias=s.shadow_normal_bias, pcf=s.shadow_pcf,
                             memory_mb=s.shadow_memory_mb)

    def may_cast_shadows(self) -> bool:
        """False when no shadow map can be needed: shadows off, the headlight, no lights, or only
        emissive materials (a light whose shadows are disabled is found by ShadowMaps itself)."""
        scene = self.scene
        if self.settings.resolved_shadows == "off" or scene.headlight or not scene.light_prims:
            return False
        return lit_materials(scene.material_table, scene.tri_material)

    def shadow_maps(self, sample_at, knots: list[Sample] | None = None) -> ShadowMaps | None:
        """Shadow maps over this frame's shutter, the scene at shutter time u given by
        sample_at(u) -> Sample; None when no light can cast a visible shadow (no time spent).
        With knots bounding all it reads (a plan's, velocity's instants), lights that darken nothing lit get none."""
        if not self.may_cast_shadows():
            return None
        sm = ShadowMaps(self.tables, self.scene.tri_vertices, self.scene.tri_object, sample_at, self.shadow_options(),
                        self.device, self.settings.threads, self.timings, self.counters, self.scene.tri_closed,
                        knots, pair_receivers(self.scene) if knots is not None else None)
        return sm if sm.active else None

    def snapshot_fraction(self, snapshot: Snapshot) -> float:
        """The shutter fraction of a snapshot (kept where it was taken: an instant shutter's
        samples share one time code, but fractional opacity samples presence per fraction)."""
        return snapshot.fraction if snapshot.fraction is not None else self.shutter_fraction(snapshot.time)

    def shutter_fraction(self, time_code: float) -> float:
        if self.shutter.instant:
            return 0.5
        return (time_code - self.shutter.open) / (self.shutter.close - self.shutter.open)

    def instant_shadow_maps(self, knots: list | None = None) -> ShadowMaps | None:
        """The shadow maps the frame's sharp instants shade with (made on first use; None when no
        light can cast a visible shadow, or, with knots (snapshots of every scene its instants
        shade; instant_knots when not given), none can darken anything lit)."""
        if self._instant_shadows is None:
            knots = [Sample.of(k) for k in (knots if knots is not None else self.instant_knots) or []] or None
            self._instant_shadows = self.shadow_maps(
                lambda u: Sample.of(self.scene.snapshot(self.shutter.time(u), with_normals=False)), knots) or False
        return self._instant_shadows or None

    def shading(self, snapshots: list[Snapshot]):
        """Shading tables for one sharp instant (with that instant's shadow maps; the last
        instant's are kept, since several passes may shade the same instant)."""
        if len(snapshots) == 1 and self._shading_last is not None and self._shading_last[0] == snapshots[0].time:
            return self._shading_last[1]
        lights = np.stack([s.lights for s in snapshots]) if snapshots else np.zeros((1, 0, 18), np.float32)
        shadows = None
        if len(snapshots) == 1:
            maps = self.instant_shadow_maps()
            if maps is not None:
                with self.timed("shadow_total"):
                    shadows = maps.data_for_instant(self.shutter_fraction(snapshots[0].time), self.instants,
                                                    self.settings.shadow_times)
        one = self.snapshot_fraction(snapshots[0]) if len(snapshots) == 1 else None
        # a sharp instant reads one or two map instants: each instant's images whole in memory
        sh = make_shading(self.scene.material_table, lights, self.scene.dome, self.device, shadows,
                          self.shadow_options(), self.scene.materials.textures, self.dome_frame(one),
                          instant_major=len(snapshots) == 1, instant_flags=self.instant_flags)
        if len(snapshots) == 1:
            self._shading_last = (snapshots[0].time, sh)
        return sh

    def bin(self, positions: np.ndarray, entry_tri: np.ndarray, entry_k0: np.ndarray,
            entry_k1: np.ndarray, counted: bool = True) -> TileBins:
        """Screen-tile bins of all entries, each tile's nearest first: a walk for the nearest hit
        stops at the first entry beyond it."""
        return self.bin_groups(positions, entry_tri, entry_k0, entry_k1, [np.ones(len(entry_tri), bool)], True,
                               counted)[0]

    def bin_groups(self, positions: np.ndarray, entry_tri: np.ndarray, entry_k0: np.ndarray, entry_k1: np.ndarray,
                   groups: list[np.ndarray], nearest_first: bool = False, counted: bool = True) -> list[TileBins]:
        """Separate screen-tile bins for each group (a boolean mask over the entries, shape (E,)),
        so a kernel can walk e.g. a tile's static entries apart from its moving ones; with
        nearest_first each tile's list runs in ascending nearest depth of its entries' vertices
        (see bin_entries), else in entry order. counted: their pairs add to stats' bin_pairs."""
        with self.timed("binning"):
            boxes, keep, bands, near = entry_bounds(self.proj, positions, self.scene.tri_vertices, entry_tri,
                                                    entry_k0, entry_k1, SAMPLE_MARGIN_PX,
                                                    threads=self.settings.threads)
            near_depth = near if nearest_first else None
            out = [bin_entries(self.proj, boxes, keep & group, TILE_SIZE, near_depth, bands) for group in groups]
        if counted:
            self.counters["bin_pairs"] = self.counters.get("bin_pairs", 0) + sum(b.num_pairs for b in out)
        return out

    def dome_frame(self, fraction: float | None = None) -> tuple | None:
        """make_shading's textured dome for this frame (None: uniform or no dome): its binding,
        camera-to-dome rotations (at shutter fraction `fraction` for one sharp instant, else at
        DOME_KNOTS even knots over the shutter, so a turning camera sweeps the map), irradiance SH
        and the map's mip level from a pixel's angle."""
        dm = self.scene.dome_map
        if dm is None:
            return None
        fractions = [fraction] if fraction is not None else np.linspace(0.0, 1.0, DOME_KNOTS)
        if self.shutter.instant:
            fractions = [0.5]
        rots = []
        for u in fractions:
            m3 = self.scene.cam_from_world(self.shutter.time(float(u)))[:3, :3]
            rots.append((np.linalg.inv(m3) @ dm.rotation).T)
        rot = np.stack(rots)
        x0, _y0, x1, _y1 = self.proj.window
        angle = (x1 - x0) / self.proj.width
        lod = -30.0 if self.proj.orthographic else float(np.log2(max(angle, 1e-12) / (2.0 * np.pi)))
        return dm.binding, rot, dm.irradiance, lod

    def view(self, bins: TileBins | None):
        return make_view(self.proj, self.settings.spatial_samples, bins, TILE_SIZE)

    def sub_pixel_offsets(self) -> list[tuple[float, float]]:
        """n×n stratified sub-pixel positions (pixel centre when n = 1), SPEC §1."""
        n = self.settings.spatial_samples
        return [((i + 0.5) / n, (j + 0.5) / n) for j in range(n) for i in range(n)]

    def receiver_velocities(self, snapshot: Snapshot) -> np.ndarray | None:
        """(V, 3) vertex velocities (units per shutter) at a sharp instant whose shading reads
        shadow maps of other instants (warped maps shared by the frame's instants), so that a
        moving receiver's lookups move with it; None when its maps are its own. The instant's
        shading knows the lights only as of this instant, in this instant's camera frame, so the
        velocities are the vertices' world motion expressed in that frame (camera motion left out),
        differenced against `neighbour` (the next instant, taken anyway) when it is set, else
        against a snapshot a quarter of an instant away."""
        maps = self._instant_shadows
        if not maps or maps.static or maps.options.mode == "direct" or self.instants <= self.settings.shadow_times:
            return None
        if self._velocities is not None and self._velocities[0] == snapshot.time:
            return self._velocities[1]
        u = self.snapshot_fraction(snapshot)
        other = self.neighbour
        if other is None or other.time == snapshot.time or other.positions.shape != snapshot.positions.shape:
            h = 0.25 / self.instants
            other = self.snapshot(u + h if u + h <= 1.0 else u - h, with_normals=False)
        u2 = self.snapshot_fraction(other)
        to_this_camera = invert_affine(other.cam_from_world) @ snapshot.cam_from_world   # row vectors
        moved = other.positions @ to_this_camera[:3, :3] + to_this_camera[3, :3]
        velocities = (moved - snapshot.positions) / (u2 - u)
        self._velocities = (snapshot.time, velocities)
        return velocities

    def static_geometry(self, snapshots: list[Snapshot], knot: int,
                        triangles: np.ndarray | None = None,
                        velocities: np.ndarray | None = None, cull: bool = True,
                        shaded: bool = True, counted: bool = True) -> tuple[Geometry, TileBins]:
        """Geometry with all snapshots as knots, and static entries at `knot` for visible triangles
        (of `triangles`, a (T,) mask, when given), moving with `velocities` for shadow lookups;
        back faces that cannot show dropped unless cull is False (raster/culling.py). Without
        `shaded` it holds no normals (depth and motion only: the snapshots need none); without
        `counted` its back faces and bin pairs stay out of the frame's counters (the AOVs' pass)."""
        positions = np.stack([s.positions for s in snapshots])
        normals = np.stack([s.normals for s in snapshots]) if self.scene.any_smooth and shaded else None
        tris, dropped = self.front_triangles(snapshots[knot], triangles, cull)
        k = np.full(len(tris), knot, np.int32)
        if counted:
            self.counters["back_faces_dropped"] = dropped
        bins = self.bin(positions, tris, k, k, counted)
        return make_geometry(self.tables, positions, normals, tris, k, k, velocities), bins

    def front_triangles(self, snapshot: Snapshot, triangles: np.ndarray | None = None,
                        cull: bool = True) -> tuple[np.ndarray, int]:
        """(tris (N,) int32, dropped): the triangles visible in `snapshot` (of `triangles`, a (T,)
        mask, when given), without the back faces that cannot show there (raster/culling.py)
        unless cull is False; dropped: how many back faces were left out."""
        visible = snapshot.tri_visible if triangles is None else snapshot.tri_visible & triangles
        tris = np.nonzero(visible)[0].astype(np.int32)
        if not cull:
            return tris, 0
        sc = self.scene
        k = np.zeros(len(tris), np.int32)
        hidden = hidden_back_faces(snapshot.positions[None], sc.tri_vertices, sc.tri_object, sc.tri_closed, tris,
                                   k, k, self.proj.near, self.proj.far, self.proj.orthographic)
        return tris[~hidden], int(hidden.sum())

    def sharp_pass(self, snapshot: Snapshot, weight: float, rgba: wp.array, pixels: np.ndarray | None = None,
                   record: bool = False, triangles: np.ndarray | None = None,
                   cull: bool = True) -> "RecordedHits | None":
        """rgba += weight × the sharp image of one instant (only at `pixels`, flat indices, if
        given, from only `triangles`, a (T,) mask, when the caller knows the others cannot show
        there). With record, returns each listed pixel's hits for prepare_reshade_pass."""
        run, hits = self.prepare_sharp_pass(snapshot, weight, rgba, pixels, record, triangles, cull)
        if run is not None:
            run()
        return hits

    def prepare_sharp_pass(self, snapshot: Snapshot, weight: float, rgba: wp.array, pixels: np.ndarray | None = None,
                           record: bool = False, triangles: np.ndarray | None = None,
                           cull: bool = True, whole_if_steady: bool = False,
                           aov_buffers: tuple[wp.array, wp.array] | None = None
                           ) -> "tuple[Callable[[], None] | None, RecordedHits | None]":
        """sharp_pass in two steps: everything up to the launch now, and (run, hits): run()
        launches it (None: nothing to render); with record, hits (RecordedHits) hold the listed
        pixels' hits once run() has returned. whole_if_steady (with record, for still surfaces under
        lights that hold still): pixels whose shadow lookups read only texels that never change are
        added at weight 1 and marked in hits.done (render_sharp's record = 2). aov_buffers (every
        pixel at weight 1, one spatial sample, no record): (depth, motion) written by the same
        visibility pass (render_sharp_depth_motion; motion 0, the snapshot being one knot)."""
        if pixels is not None and len(pixels) == 0:
            return None, None
        sh = self.shading([snapshot])
        geo, bins = self.static_geometry([snapshot], 0, triangles, self.receiver_velocities(snapshot), cull)
        view, b = self.view(bins), make_bins(bins, self.device)
        u = self.snapshot_fraction(snapshot)   # static entries ignore it; shadow maps shared over time use it
        self.skip_unshadowed(sh, geo, u)
        dev = self.device
        count = self.num_pixels if pixels is None else len(pixels)
        listed = wp.array(pixels.astype(np.int32), dtype=int, device=dev) if pixels is not None else \
            wp.zeros(1, dtype=int, device=dev)
        subs = self.settings.spatial_samples ** 2
        rows = count if record else 1
        rec_e = wp.zeros((rows, subs if record else 1), dtype=int, device=dev)
        rec_hit = wp.zeros((rows, subs if record else 1), dtype=wp.vec4, device=dev)
        whole = record and whole_if_steady
        done = wp.zeros(rows if whole else 1, dtype=wp.uint8, device=dev)
        mode = 2 if whole else (1 if record else 0)

        def run() -> None:
            if aov_buffers is not None:
                assert pixels is None and not record and weight == 1.0 and subs == 1
                no_gather = wp.zeros(0, dtype=wp.vec2, device=dev)
                with self.timed("render"):
                    launch_pixels(render_sharp_depth_motion, count,
                                  lambda first, _n: [view, geo, sh, b, u, 0, 0, first, rgba, *aov_buffers, no_gather],
                                  dev, self.settings.threads, bands_per_thread=FINE_BANDS, widest=SHARP_WIDEST)
                return
            with self.timed("render"):
                launch_pixels(render_sharp, count,
                              lambda first, _n: [view, geo, sh, b, u, weight, listed, 0 if pixels is None else 1,
                                                 first, mode, rgba, rec_e, rec_hit, done], dev,
                              self.settings.threads, bands_per_thread=FINE_BANDS, widest=SHARP_WIDEST)
        return run, (RecordedHits(view, listed, rec_e, rec_hit, done=done if whole else None) if record else None)

    def skip_unshadowed(self, sh, geo: Geometry, u: float) -> None:
        """Flag the entries of geo (a sharp instant at shutter time u) that no shadow of sh's maps
        reaches, so their shading makes no lookup (shadows/free_entries.py). The maps' occupancy is
        found once for the instants that share them; one launch each, no thread pool (passes are
        prepared beside the pool's work)."""
        from ..shadows.free_entries import flag_shadow_free, occupancy_table
        last = self._occupancy_last
        if last is None or last[0] is not sh.shadow_maps:
            last = self._occupancy_last = (sh.shadow_maps, occupancy_table(sh, self.device, 1))
        flag_shadow_free(sh, last[1], geo, geo.entry_tri.shape[0], self.device, self.counters, sharp_at=u)

    def per_triangle_geometry(self, snapshot: Snapshot) -> Geometry:
        """The instant's Geometry with every triangle an entry (entry = triangle index), static at
        its one knot: what recorded hits index. The last one is kept, since an instant's reshade
        and moving-tile passes both use it."""
        last = self._per_triangle_last
        if last is not None and last[0] is snapshot:
            return last[1]
        tris = np.arange(self.scene.num_triangles, dtype=np.int32)
        k = np.zeros(len(tris), np.int32)
        normals = snapshot.normals[None] if self.scene.any_smooth else None
        geo = make_geometry(self.tables, snapshot.positions[None], normals, tris, k, k,
                            self.receiver_velocities(snapshot))
        self._per_triangle_last = (snapshot, geo)
        return geo

    def prepare_reshade_pass(self, snapshot: Snapshot, hits: "RecordedHits", weight: float,
                             rgba: wp.array) -> Callable[[], None]:
        """A pass that, run, adds weight × the sharp image of one instant at the recorded pixels,
        whose visibility does not change: their recorded hits shaded with this instant's lights
        and shadows."""
        sh = self.shading([snapshot])
        geo = self.per_triangle_geometry(snapshot)
        u = self.snapshot_fraction(snapshot)

        def run() -> None:
            rows, count = hits.pixels, hits.pixels.shape[0]
            if hits.done is not None:   # recorded by now: only the pixels not added whole
                if hits.pending is None:
                    pending = np.nonzero(hits.done.numpy() == 0)[0].astype(np.int32)
                    hits.pending = wp.array(pending, dtype=int, device=self.device) if len(pending) else None
                    hits.pending_count = len(pending)
                rows, count = hits.pending, hits.pending_count
            if count == 0:
                return
            use_rows = 1 if hits.done is not None else 0
            with self.timed("render"):
                launch_pixels(shade_recorded, count,
                              lambda first, _n: [hits.view, geo, sh, u, weight, hits.pixels, first, hits.entries,
                                                 hits.hits, rows, use_rows, rgba], self.device, self.settings.threads,
                              bands_per_thread=FINE_BANDS, widest=SHARP_WIDEST)
        return run

    def prepare_record_pass(self, snapshot: Snapshot, pixels: np.ndarray, triangles: np.ndarray,
                            shade: int) -> "tuple[Callable[[], None], RecordedHits]":
        """(run, hits): run() records, at the listed pixels (flat indices), each sub-sample's nearest
        hit at this instant among `triangles` (a (T,) mask) and, with shade = 1, its radiance then
        (for every instant), with shade = 2 (still lights, shadows that may change) its radiance
        where its shadow lookups never change; nothing is added to the image
        (prepare_over_recorded_pass composites it)."""
        sh = self.shading([snapshot])
        geo, bins = self.static_geometry([snapshot], 0, triangles, self.receiver_velocities(snapshot))
        view, b = self.view(bins), make_bins(bins, self.device)
        u = self.snapshot_fraction(snapshot)
        dev = self.device
        listed = wp.array(pixels.astype(np.int32), dtype=int, device=dev)
        subs = self.settings.spatial_samples ** 2
        rec_e = wp.zeros((len(pixels), subs), dtype=int, device=dev)
        rec_hit = wp.zeros((len(pixels), subs), dtype=wp.vec4, device=dev)
        shape = rec_e.shape if shade else (1, 1)
        rec_color = wp.zeros(shape, dtype=wp.vec3, device=dev)
        rec_kept = wp.zeros(shape, dtype=wp.uint8, device=dev)

        def run() -> None:
            with self.timed("render"):
                launch_pixels(record_nearest, len(pixels),
                              lambda first, _n: [view, geo, sh, b, u, listed, first, shade, rec_e, rec_hit, rec_color,
                                                 rec_kept], dev, self.settings.threads, bands_per_thread=FINE_BANDS,
                              widest=SHARP_WIDEST)
        return run, RecordedHits(view, listed, rec_e, rec_hit, rec_color if shade else None,
                                 kept=rec_kept if shade else None)

    def prepare_over_recorded_pass(self, snapshot: Snapshot, hits: "RecordedHits", triangles: np.ndarray,
                                   weight: float, rgba: wp.array, instants: np.ndarray | None = None,
                                   rgba_odd: wp.array | None = None) -> "Callable[[], None] | None":
        """A pass that, run, adds weight × the sharp image of one instant at the recorded pixels,
        where the recorded surfaces (prepare_record_pass) stand still and only `triangles` (a (T,)
        mask) change: those are rasterised and the nearer of them and the recorded hit shown (the
        recorded one with its recorded radiance where hits.kept says so, else shaded now). Equal
        to sharp_pass over both sets, at the cost of rasterising the changing ones only.

        With `instants` (shutter fractions), one pass adds weight × each of those instants' images
        in turn, for a frame where nothing moves, shading is steady (hits recorded with their
        radiance) and `triangles` change only in presence: render_over_recorded_instants, each
        changing surface shaded once per sub-sample instead of once per instant; the odd-indexed
        instants then add into rgba_odd when given (accumulation's half sums, methods/halves.py)."""
        tris, _ = self.front_triangles(snapshot, triangles)
        k = np.zeros(len(tris), np.int32)
        # the bins list triangle indices: every triangle is an entry of the instant's geometry
        bins = self.bin(snapshot.positions[None], tris, k, k).by_triangle(tris, self.scene.num_triangles)
        geo = self.per_triangle_geometry(snapshot)
        sh = self.shading([snapshot])
        b = make_bins(bins, self.device)
        u = self.snapshot_fraction(snapshot)
        kept = 1 if hits.colors is not None else 0
        colors = hits.colors if hits.colors is not None else wp.zeros((1, 1), dtype=wp.vec3, device=self.device)
        kept_flags = hits.kept if hits.kept is not None else wp.zeros((1, 1), dtype=wp.uint8, device=self.device)
        view = self.view(bins)
        if instants is not None:
            assert hits.colors is not None, "instants in one pass need the recorded radiance"
            count = hits.pixels.shape[0]
            slots = hits.entries.shape[1] * INSTANT_CACHE_SLOTS
            us = wp.array(np.asarray(instants, np.float32), dtype=float, device=self.device)
            cache_e = wp.empty((count, slots), dtype=int, device=self.device)
            cache_color = wp.empty((count, slots), dtype=wp.vec3, device=self.device)

            def run_instants() -> None:
                with self.timed("render"):
                    launch_pixels(render_over_recorded_instants, count,
                                  lambda first, _n: [view, geo, sh, b, us, weight, hits.pixels, first, hits.entries,
                                                     hits.hits, hits.colors, cache_e, cache_color, rgba,
                                                     rgba if rgba_odd is None else rgba_odd],
                                  self.device, self.settings.threads, bands_per_thread=FINE_BANDS, widest=SHARP_WIDEST)
            return run_instants

        def run() -> None:
            with self.timed("render"):
                launch_pixels(render_over_recorded, hits.pixels.shape[0],
                              lambda first, _n: [view, geo, sh, b, u, weight, hits.pixels, first, kept,
                                                 hits.entries, hits.hits, colors, kept_flags, rgba], self.device,
                              self.settings.threads, bands_per_thread=FINE_BANDS, widest=SHARP_WIDEST)
        return run
