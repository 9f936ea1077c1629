"""Shadow maps in motion: per shadowing light, depth maps at the instants shading needs, rendered
directly (the reference) or warped from a few key maps through a mesh of control points.

Frames. A light's frame is rigid with the light (its USD transform: origin and local axes, in
camera space at each instant), so a light that does not move in the world gives the same map
whatever the camera does. Each light has faces fixed for the frame: orthographic along the light
for distant lights; for sphere, disk and rect lights one perspective frustum fitted to the
geometry when it all lies within 60° of one direction, else the six faces of a cube. Windows are
fitted to the geometry at the probe instants (open, centre, close, and the keys).

Area lights (sphere with a radius, disk, rect) are M point samples on the light, each with its own
maps; shading averages the M depth comparisons (soft shadows). A sample's map is warped from the
light centre's key maps (a moved light is the occluder moved the opposite way), or rendered
directly in direct mode. Warping is shadows/warped.py's; a time-continuous frame's direct maps are
splatted a face (all its instants) at a time straight into the layout its lookups read
(texel_major.py).
"""

from __future__ import annotations

import threading
import time
from typing import Callable

import numpy as np
import warp as wp

from ..raster.device_data import TriangleTables
from ..usd.lights import DISK, DISTANT, RECT, SPHERE
from ..core.log import warn_once
from ..core.parallel import default_threads, map_threads
from ..core.rows import any_corner
from ..kernels.shadow_lookup import FACE_WIDTH
from ..raster.culling import instance_volume_sign
from .casters import light_casters, used_vertex_index
from .direct import STILL_PROBES, FaceRasterizer, still_triangles
from .layout import (FAR, Face, LightLayout, Sample, ShadowData, ShadowOptions, distant_face, fit_faces, light_frame,
                     light_sample_offsets)
from .pairs import responds_to_light, unneeded_lights
from .texel_major import TexelMajorLayout
from .vertex_passes import light_fit
from .warped import KeyWarping

#: cost of warping one texel of a map (host-side mesh and gather kernel, seconds), measured by
#: bench/bench_shadows.py on this project's 2-core machine; replaced by this process's own
#: measurement once it has warped a map. `--shadows auto` weighs it against the measured cost of
#: rendering the light's first map directly.
WARP_SECONDS_PER_TEXEL = 3.5e-7
#: shutter times at which closed instances' volume signs must agree for their back faces to be culled
SIGN_PROBES = (0.0, 0.5, 1.0)
#: light-local coordinates (scene units) beyond which a point is left out of its light's map fit:
#: float32 cannot hold the fitted windows and depths (a prim at 1e300 made them inf, and every
#: lookup NaN), and one such prim would stretch a map over all the rest anyway
FIT_LIMIT = 1.0e18
#: a key map (depth, triangle and barycentrics gathered per texel) costs this many direct maps
KEY_MAP_COST = 1.75


class ShadowMaps(KeyWarping):
    """The shadow maps of one frame: built on demand for the instants shading asks for."""

    def __init__(self, tables: TriangleTables, tri_vertices: np.ndarray, tri_object: np.ndarray,
                 sample_at: Callable[[float], Sample], options: ShadowOptions,
                 device: str, threads: int | None, timings: dict, counters: dict,
                 tri_closed: np.ndarray | None = None, knots: list[Sample] | None = None,
                 receivers: tuple[np.ndarray, np.ndarray] | None = None) -> None:
        """knots: samples whose consecutive pairs hold, linearly, every sample sample_at gives (a
        motion plan's knots), and receivers: (tri_receives, tri_self_safe), (T,) bool each (pairs.py):
        given both, the lights that can darken nothing lit get no maps."""
        self.tables = tables
        self.tri_vertices = tri_vertices
        self.tri_object = tri_object
        self.options = options
        self.device = device
        self.threads = threads
        self.timings = timings
        self.counters = counters
        self._samples: dict[float, Sample] = {}
        self._sample_fn = sample_at
        self._keys: dict[tuple[int, int], list[tuple[np.ndarray, np.ndarray, np.ndarray]]] = {}
        self._key_dev: dict[tuple[int, int], wp.array] = {}
        self._static_data: ShadowData | None = None
        self._meshes: dict = {}
        self._binned: ShadowData | None = None
        self._still: dict[int, np.ndarray] = {}
        self._used_index: dict[bytes, np.ndarray] = {}   # visibility mask -> its vertices (_used_vertices)
        self._casters: dict[int, np.ndarray | None] = {}   # per light row: (T,) triangles that may cast
        self._raster = FaceRasterizer(tables, tri_vertices, options.size, device, tri_object)
        self._lock = threading.Lock()
        self._bases: dict[tuple[int, int, int], np.ndarray] = {}
        self.size = options.size
        self.layouts: list[LightLayout] = []
        self._warp_seconds_per_texel = WARP_SECONDS_PER_TEXEL
        centre = self.sample(0.5)
        self.num_lights = len(centre.lights)
        if options.mode == "off" or len(tri_vertices) == 0:
            return
        rows = [j for j in range(len(centre.lights)) if centre.lights[j, 17] > 0.5]
        t0 = time.perf_counter()
        if rows and knots is not None and receivers is not None:
            unneeded = unneeded_lights(rows, knots, tri_vertices, tri_object, *receivers)
            needed = [j for j in rows if j not in unneeded]
            self.counters["shadow_lights_unneeded"] = len(rows) - len(needed)
            rows = needed
            if not rows:
                self._add_time("shadow_setup", time.perf_counter() - t0)
        if not rows:
            return
        self._plan(rows)
        if tri_closed is not None and tri_closed.any() and len(tri_object):
            # closed instances' volume signs at shutter open, centre and close (camera space: a sign
            # is the same in every light's frame; it changes only through a degenerate, flat mesh):
            # their back faces are left out of the maps
            probes = [self.sample(u) for u in SIGN_PROBES]
            if all(p.positions.shape == probes[0].positions.shape for p in probes):
                self._raster.object_sign = instance_volume_sign(
                    np.stack([p.positions for p in probes]), tri_vertices, tri_object, tri_closed, -np.inf, np.inf)
        self._add_time("shadow_setup", time.perf_counter() - t0)

    # ------------------------------------------------------------------------------ layout
    @property
    def active(self) -> bool:
        return bool(self.layouts)

    @property
    def static(self) -> bool:
        return all(lay.static for lay in self.layouts)

    def sample(self, u: float) -> Sample:
        u = float(u)
        with self._lock:
            if u not in self._samples:
                if len(self._samples) > 16:
                    self._samples.clear()
                self._samples[u] = self._sample_fn(u)
            return self._samples[u]

    def _add_time(self, name: str, dt: float) -> None:
        with self._lock:
            self.timings[name] = self.timings.get(name, 0.0) + dt

    def _count(self, name: str, n: int) -> None:
        with self._lock:
            self.counters[name] = self.counters.get(name, 0) + n

    def _used(self, s: Sample) -> np.ndarray:
        """(U,) ascending indices of the vertices of s's visible triangles (all triangles' when it
        has no visibility), remembered per visibility mask (the probes of a frame mostly share one)."""
        key = s.tri_visible.tobytes() if len(s.tri_visible) else b""
        index = self._used_index.get(key)
        if index is None:
            visible = s.tri_visible if len(s.tri_visible) else np.ones(len(self.tri_vertices), bool)
            index = self._used_index[key] = used_vertex_index(visible, self.tri_vertices, len(s.positions))
        return index

    def _used_vertices(self, s: Sample) -> np.ndarray:
        """(U, 3) positions at s of the vertices of its visible triangles, in index order."""
        return s.positions[self._used(s)]

    def _local(self, j: int, s: Sample) -> np.ndarray:
        origin, axes = light_frame(s.lights[j])
        return (self._used_vertices(s) - origin) @ axes.T

    def _plan(self, rows: list[int]) -> None:
        o = self.options
        probes = [self.sample(u) for u in (0.0, 0.5, 1.0)]
        for j in rows:
            row = probes[1].lights[j]
            kind = int(row[0])
            if kind == DISTANT:   # its face needs only bounds: kernel passes (vertex_passes.light_fit)
                lo, hi, top, count, change = light_fit([(s.positions, self._used(s), light_frame(s.lights[j]))
                                                        for s in probes], FIT_LIMIT, self.threads)
                if count == 0:
                    continue
                static = change is not None and change <= 1e-9 * (top + 1.0)
                static &= all(np.array_equal(s.tri_visible, probes[0].tri_visible) for s in probes[1:])
                self.layouts.append(LightLayout(j, kind, np.zeros((1, 3)), [distant_face(lo[:2], hi[:2])], static))
                continue
            locs = [self._local(j, s) for s in probes]
            allp = np.concatenate(locs)
            allp = allp[(np.abs(allp) <= FIT_LIMIT).all(axis=1)]   # (NaN fails too)
            if len(allp) == 0:
                continue
            towards = allp.mean(axis=0)
            towards = towards / max(np.linalg.norm(towards), 1e-30) if np.linalg.norm(towards) > 0 else np.array([0, 0, -1.0])
            soft = kind in (RECT, DISK) or (kind == SPHERE and row[16] > 0)
            offsets = light_sample_offsets(row, o.light_samples if soft else 1, towards)
            pts = np.concatenate([allp - off for off in offsets]) if len(offsets) > 1 else allp
            faces = fit_faces(kind, pts, self.size)
            extent = float(np.abs(allp).max()) + 1.0
            with np.errstate(invalid="ignore"):   # (inf - inf far beyond the fit: not static)
                static = all(a.shape == locs[0].shape and np.abs(a - locs[0]).max(initial=0.0) <= 1e-9 * extent
                             for a in locs[1:])
            static &= all(np.array_equal(s.tri_visible, probes[0].tri_visible) for s in probes[1:])
            self.layouts.append(LightLayout(j, kind, offsets, faces, static))
        self._plan_casters(probes[1])
        self.counters["shadow_lights"] = len(self.layouts)
        self.counters["shadow_light_samples"] = [len(lay.offsets) for lay in self.layouts]
        self.counters["shadow_faces"] = [len(lay.faces) for lay in self.layouts]
        self.counters["shadow_map_size"] = self.size
        self.counters["shadow_mode"] = o.mode

    def _plan_casters(self, centre: Sample) -> None:
        """Each light's triangles that may cast a shadow (casters.light_casters)."""
        self._casters, self.counters["shadow_non_casters"] = light_casters(
            self.layouts, centre, lambda lay: [centre] if lay.static else [self.sample(u) for u in STILL_PROBES],
            self.tri_vertices)

    def times_for(self, requested: int) -> int:
        """Map instants for the time-continuous methods: 1 when nothing moves in any light's view,
        else `requested`, halved while one frame's maps exceed the memory budget."""
        if self.static:
            return 1
        b = max(requested, 1)
        per_time = sum(len(lay.offsets) * len(lay.faces) for lay in self.layouts) * self.size ** 2 * 4
        while b > 2 and per_time * b > self.options.memory_mb * 2**20:
            b //= 2
        if b < requested:
            warn_once(f"shadow-budget:{b}:{requested}:{self.options.memory_mb:g}", f"shadow maps: {b} instants instead of {requested} to stay within "
                                       f"{self.options.memory_mb:g} MB")
        return b

    # ------------------------------------------------------------------------------ transforms
    def _face_transform(self, lay: LightLayout, face: Face, m: int, s: Sample) -> tuple[np.ndarray, np.ndarray]:
        """(A (3, 3), t (3,)) with face-space q = A p + t for light sample m at sample s."""
        origin, axes = light_frame(s.lights[lay.row])
        a = face.rotation @ axes
        o = origin + lay.offsets[m] @ axes
        return a, -a @ o

    # ------------------------------------------------------------------------------ rendering
    def _still_triangles(self, lay: LightLayout) -> np.ndarray:
        """(T,) bool: the triangles that hold still in light lay's frame (direct.still_triangles)."""
        if lay.row not in self._still:
            self._still[lay.row] = still_triangles([self.sample(u) for u in STILL_PROBES], lay.row, self.tri_vertices,
                                                   self.threads)
            self.counters["shadow_still_triangles"] = max(self.counters.get("shadow_still_triangles", 0),
                                                          int(self._still[lay.row].sum()))
        return self._still[lay.row]

    def _depth_over(self, lay: LightLayout, fi: int, m: int, s: Sample, subset: np.ndarray | None,
                    base: np.ndarray | None, threads: int | None) -> np.ndarray:
        a, t = self._face_transform(lay, lay.faces[fi], m, s)
        return self._raster.depth_over(a, t, lay.faces[fi], s, self._cast(lay, subset), base, threads)

    def _cast(self, lay: LightLayout, subset: np.ndarray | None) -> np.ndarray | None:
        """subset (a (T,) mask, None: all) without the triangles that cannot cast from lay."""
        casters = self._casters.get(lay.row)
        if casters is None:
            return subset
        return casters if subset is None else subset & casters

    def _base(self, lay: LightLayout, fi: int, m: int, target: Sample, still: np.ndarray,
              threads: int | None) -> np.ndarray:
        """The still triangles' base map of face fi, light sample m (rendered at target once)."""
        key = (lay.row, m, fi)
        if key not in self._bases:
            self._bases[key] = self._depth_over(lay, fi, m, target, still, None, threads)
            self._count("shadow_maps_still_base", 1)
        return self._bases[key]

    def _direct_depth(self, lay: LightLayout, fi: int, m: int, u: float, threads: int | None = None) -> np.ndarray:
        """Depth (S, S) of face fi, light sample m, at shutter time u, rendered. The triangles
        that hold still in the light's frame are rendered once into a base map and each instant
        renders only the others over it (the nearer depth wins): still occluders under a still
        light cost one map, even seen from a moving camera."""
        threads = threads or self.threads
        target = self.sample(0.5 if lay.static else u)
        still = None if lay.static else self._still_triangles(lay)
        if still is None or not still.any():
            depth = self._depth_over(lay, fi, m, target, None, None, threads)
        else:
            depth = self._base(lay, fi, m, target, still, threads)
            if not still.all():
                depth = self._depth_over(lay, fi, m, target, ~still, depth, threads)
        self._count("shadow_maps_rendered", 1)
        return depth

    def _render_direct(self, work: list[tuple[LightLayout, list[tuple[int, int, int, float]]]],
                       put: Callable[[int, np.ndarray], None], laid: TexelMajorLayout | None = None) -> None:
        """Render the lights' direct maps (per light, jobs (map index, face, light sample, time)).
        Still bases (one per light, face and sample) are rendered first, so no two threads render
        the same one. Without `laid`, one map per pool thread as a single-core launch (put(index,
        depth) stores it): a map's host-side setup overlaps the other threads' rasterizing. With
        `laid`, one face per pool thread: its instants splatted together in one single-core launch
        straight into its texel-major slot (_render_slot)."""
        work = [(lay, jobs) for lay, jobs in work if jobs]
        if not work:
            return
        t0 = time.perf_counter()
        threads = self.threads or default_threads()
        single = 1 if threads > 1 and sum(len(jobs) for _lay, jobs in work) > 1 else None
        bases = []
        for lay, jobs in work:
            still = None if lay.static else self._still_triangles(lay)
            if still is not None and still.any():
                first: dict[tuple[int, int], float] = {}
                for _idx, fi, m, u in jobs:
                    first.setdefault((fi, m), u)
                bases += [(lay, fi, m, u, still) for (fi, m), u in first.items()]
        map_threads(lambda b: self._base(b[0], b[1], b[2], self.sample(b[3]), b[4], single), bases, threads)
        if laid is None:
            def one(item: tuple[LightLayout, tuple[int, int, int, float]]) -> None:
                lay, (idx, fi, m, u) = item
                put(idx, self._direct_depth(lay, fi, m, u, single))
            map_threads(one, [(lay, job) for lay, jobs in work for job in jobs], threads)
        else:
            groups: dict[tuple[int, int, int], tuple[LightLayout, list[tuple[int, float]]]] = {}
            for lay, jobs in work:
                for idx, fi, m, u in jobs:
                    groups.setdefault((lay.row, m, fi), (lay, []))[1].append((idx, u))
            # a face per pool thread, as single-core launches; the faces with the most triangles
            # first, so the last to finish is a small one
            order = sorted(groups.items(), key=lambda g: -self._face_load(g[1][0], g[0][2]))
            map_threads(lambda g: self._render_slot(g[1][0], g[0][2], g[0][1], g[1][1], laid, single), order,
                        threads)
        self._add_time("shadow_render", time.perf_counter() - t0)

    def _face_load(self, lay: LightLayout, fi: int) -> int:
        """Rough cost of rendering face fi of a light: the triangles whose vertices it may see
        (at the shutter centre)."""
        s = self.sample(0.5)
        face = lay.faces[fi]
        a, t = self._face_transform(lay, face, self._centre(lay), s)
        q = s.positions @ a.T + t
        depth = -q[:, 2]
        if face.ortho:
            return len(self.tri_vertices)
        x0, y0, x1, y1 = face.window
        with np.errstate(divide="ignore", invalid="ignore"):
            inside = (depth > face.near) & (q[:, 0] >= x0 * depth) & (q[:, 0] <= x1 * depth) \
                & (q[:, 1] >= y0 * depth) & (q[:, 1] <= y1 * depth)
        return int(np.count_nonzero(any_corner(inside, self.tri_vertices)))

    def _render_slot(self, lay: LightLayout, fi: int, m: int, items: list[tuple[int, float]],
                     laid: TexelMajorLayout, threads: int | None) -> None:
        """Render face fi, light sample m at the items' instants (map index, time) straight into
        its texel-major slot: the still triangles' base map under each instant, the moving
        triangles of every instant splatted in one launch; then flag the slot's varying texels
        (its other instants, if any, are in place already)."""
        slot = laid.locate(items[0][0])[0]
        instants = [laid.locate(idx)[1] for idx, _u in items]
        whole = len(set(instants)) == laid.times   # every instant filled here, over the same base
        if lay.static:   # nothing moves in the light's view: one map serves every instant
            laid.fill(slot, instants, self._direct_depth(lay, fi, m, 0.5, threads))
            laid.settle(slot, whole)
            return
        self._count("shadow_maps_rendered", len(items))
        still = self._still_triangles(lay)
        base = self._bases.get((lay.row, m, fi)) if still.any() else None
        laid.fill(slot, instants, base)
        moving = None if base is None else ~still
        geo = None
        if moving is None or moving.any():
            samples = [self.sample(u) for _idx, u in items]
            transforms = [self._face_transform(lay, lay.faces[fi], m, smp) for smp in samples]
            geo = self._raster.instants_geometry(transforms, samples, instants, laid.times, self._cast(lay, moving),
                                                 lay.faces[fi])
        if geo is None:   # the base alone
            laid.settle(slot, whole)
            return
        target = laid.target(slot, self.device)
        touched = laid.flags(slot, self.device) if whole else self._raster.no_flags   # whole: flags from the splat
        self._raster.splat_instants(lay.faces[fi], geo, laid.times, target, touched, threads,
                                    laid.occupied_slot(slot, self.device), laid.block)
        laid.done(slot, target, touched)
        if not whole:
            laid.flag(slot)

    # ------------------------------------------------------------------------------ assembly
    def data(self, times: list[float], texel_major: bool = False) -> ShadowData | None:
        """Maps for the given shutter instants (B = len(times)); None without shadowing lights.
        Static shadows are built once (at the shutter centre) and serve every instant. texel_major:
        also lay the maps out, while they render, as spans of time read them (TexelMajorLayout)."""
        if not self.active:
            return None
        if self.static:
            if self._static_data is None:
                self._static_data = self._build([0.5], direct=True, frame_instants=1)
            return self._static_data
        return self._build(times, direct=self.options.mode == "direct", frame_instants=len(times),
                           texel_major=texel_major)

    def data_for_instant(self, u: float, num_instants: int, requested_times: int) -> ShadowData | None:
        """Maps for a sharp instant u of a frame shading `num_instants` instants. Direct mode (the
        reference) renders maps at u itself; warped mode warps maps to u, or, when the frame has
        more instants than `requested_times`, warps maps once at those instants and every instant
        interpolates their comparisons (as stochastic and analytic do)."""
        if not self.active or self.static or self.options.mode == "direct" or num_instants <= requested_times:
            if not self.active or self.static:
                return self.data([u])
            return self._build([u], direct=self.options.mode == "direct", frame_instants=num_instants)
        if self._binned is None:
            b = self.times_for(requested_times)
            self._binned = self.data([(i + 0.5) / b for i in range(b)])
        return self._binned

    def _warp_pays(self, lay: LightLayout, map_seconds: float, remaining_maps: int) -> bool:
        """Auto mode: True when warping the light's remaining maps of the frame (after paying for
        its key maps) is cheaper than rendering them as the first one was rendered (map_seconds)."""
        keys = 2 * len(lay.faces) * len(lay.offsets)   # open and close at least
        warped = keys * KEY_MAP_COST * map_seconds + remaining_maps * self.size ** 2 * self._warp_seconds_per_texel
        return remaining_maps * map_seconds > warped

    def _build(self, times: list[float], direct: bool, frame_instants: int,
               texel_major: bool = False) -> ShadowData:
        """Maps at `times` (B shutter instants); frame_instants: how many instants the frame
        builds maps for in all (auto mode weighs warping against rendering over all of them);
        texel_major (B > 1): the maps rendered straight into the layout spans of time read."""
        t_start = time.perf_counter()
        s = self.size
        total = sum(len(lay.offsets) * len(lay.faces) for lay in self.layouts) * len(times)
        faces = np.zeros((total, FACE_WIDTH), np.float32)
        info = np.full((max(self.num_lights, 1), 3), -1, np.int32)
        laid = TexelMajorLayout(total // len(times), s, len(times)) if texel_major and len(times) > 1 else None
        maps = np.empty((total, s, s), np.float32) if laid is None else None

        def put(idx: int, depth: np.ndarray) -> None:
            if laid is None:
                maps[idx] = depth
            else:
                laid.put(idx, depth)
        idx = 0
        direct_jobs = []   # per light: its maps to render in parallel, all lights' at once below
        for lay in self.layouts:
            info[lay.row] = (idx, len(lay.offsets), len(lay.faces))
            if laid is not None:
                laid.add_light(idx, len(lay.offsets), len(lay.faces))
            if direct or lay.static:
                lay.warp = False
            elif self.options.mode == "warped":
                lay.warp = True
            keys = self._key_times(lay) if lay.warp else None
            rendered = 0
            if keys is not None:
                self.counters["shadow_keys"] = max(self.counters.get("shadow_keys", 0), len(keys))
            jobs: list[tuple[int, int, int, float]] = []   # direct maps, rendered in parallel below
            done: set[int] = set()
            if lay.warp is None and laid is not None:
                # auto, texel-major: the light's first face at every instant, rendered as its direct
                # faces would be, decides (its still base rendered beforehand: paid whatever the mode)
                still = self._still_triangles(lay)
                if still.any():
                    self._base(lay, 0, 0, self.sample(times[0]), still, None)
                first = [(idx + b * len(lay.faces), u) for b, u in enumerate(times)]
                t0 = time.perf_counter()
                self._render_slot(lay, 0, 0, first, laid, None)
                seconds = time.perf_counter() - t0
                self._add_time("shadow_render", seconds)
                done = {i for i, _u in first}
                n = frame_instants * len(lay.offsets) * len(lay.faces) - len(first)
                lay.warp = self._warp_pays(lay, seconds / len(first), n)
                self.counters.setdefault("shadow_warped_lights", []).append(int(lay.warp))
                keys = self._key_times(lay) if lay.warp else None
            for m in range(len(lay.offsets)):
                for u in times:
                    for fi, face in enumerate(lay.faces):
                        queued = keys is None and lay.warp is not None
                        if idx in done:
                            pass
                        elif queued:
                            jobs.append((idx, fi, m, u))
                        elif keys is None:
                            t0 = time.perf_counter()
                            bases = self.counters.get("shadow_maps_still_base", 0)
                            put(idx, self._direct_depth(lay, fi, m, u))
                            self._add_time("shadow_render", time.perf_counter() - t0)
                            rendered += 1
                            # auto: the light's first map decides (the first over a still base
                            # rendered beforehand: the base is paid once, whatever the mode)
                            if bases == self.counters.get("shadow_maps_still_base", 0):
                                n = frame_instants * len(lay.offsets) * len(lay.faces) - rendered
                                lay.warp = self._warp_pays(lay, time.perf_counter() - t0, n)
                                self.counters.setdefault("shadow_warped_lights", []).append(int(lay.warp))
                                if lay.warp:
                                    keys = self._key_times(lay)
                        else:
                            put(idx, self._warp_face(lay, fi, m, u, keys))
                            self._count("shadow_maps_warped", 1)
                        faces[idx, 0:9] = face.rotation.ravel()
                        faces[idx, 9:12] = lay.offsets[m]
                        faces[idx, 12:16] = face.window
                        faces[idx, 16] = 1.0 if face.ortho else 0.0
                        faces[idx, 17] = face.near if not face.ortho else -FAR
                        faces[idx, 18] = 1.0 if face.cube else 0.0
                        faces[idx, 19:22] = face_scales(face.window, s)
                        idx += 1
            direct_jobs.append((lay, jobs))
        self._render_direct(direct_jobs, put, laid)
        if laid is not None:
            laid.finish()
        self._add_time("shadows", time.perf_counter() - t_start)
        return ShadowData(maps, faces, info, len(times), s, self.counters, texel_major=laid)


def face_scales(window: tuple[float, float, float, float], size: int) -> tuple[float, float, float]:
    """(texels per window unit in x, in y, window units per texel in x) of a face's window (x0,
    y0, x1, y1) at size texels a side: the lookup multiplies where it would divide."""
    x0, y0, x1, y1 = (float(v) for v in window)
    return size / (x1 - x0), size / (y1 - y0), (x1 - x0) / size


def lit_materials(material_table: np.ndarray, tri_material: np.ndarray) -> bool:
    """True when some triangle's material responds to lights (shadows can change a pixel)."""
    if len(tri_material) == 0:
        return False
    return bool(responds_to_light(material_table[np.unique(tri_material)]).any())
