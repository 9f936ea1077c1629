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
directly in direct mode.

Warping. Key maps are rendered at a few shutter instants (open and close, and more while the
light-space motion between keys is more than a texel from linear). Each key texel knows the
triangle and barycentrics it sees, so a grid of control points (every `grid`-th texel) follows the
scene's own motion to any instant and light position. The grid's cells are warped as triangles
(per target texel: key depth at the back-mapped source texel plus the interpolated depth change);
cells that span a depth discontinuity or two objects are cut and their texels warped one by one
with their own motion; the two keys bracketing the instant are warped and the nearer depth kept,
so what one key hides the other shows. Depths are compared after warping, never averaged.
"""

from __future__ import annotations

import threading
import time
from typing import Callable

import numpy as np
import warp as wp

from ..raster.binning import bin_entries
from ..raster.device_data import TriangleTables, device_array
from ..usd.lights import DISK, RECT, SPHERE
from ..core.log import warn_once
from ..core.parallel import default_threads, launch_pixels, map_threads
from ..kernels.shadow_lookup import FACE_WIDTH
from ..kernels.shadow_raster import warp_texels
from .casters import light_casters
from .direct import STILL_PROBES, FaceRasterizer, still_triangles
from .layout import (FAR, Face, KeyMesh, LightLayout, Sample, ShadowData, ShadowOptions, fit_faces, light_frame,
                     light_sample_offsets)
from .texel_major import TexelMajorLayout

#: cells whose key depths differ by more than this many cell widths are cut (depth discontinuity)
JUMP_CELLS = 8.0
#: tile size (texels) of the warped triangles' bins: small, since control-point cells are small
WARP_TILE = 8
#: cost of warping one texel of a map (host-side mesh and gather kernel, seconds), measured by
#: bench/bench_shadows.py on this project's 2-core machine; replaced by this process's own
#: measurement once it has warped a map. `--shadows auto` weighs it against the measured cost of
#: rendering the light's first map directly.
WARP_SECONDS_PER_TEXEL = 3.5e-7
#: a key map (depth, triangle and barycentrics gathered per texel) costs this many direct maps
KEY_MAP_COST = 1.75


class ShadowMaps:
    """The shadow maps of one frame: built on demand for the instants shading asks for."""

    def __init__(self, tables: TriangleTables, tri_vertices: np.ndarray, tri_object: np.ndarray,
                 sample_at: Callable[[float], Sample], options: ShadowOptions,
                 device: str, threads: int | None, timings: dict, counters: dict) -> None:
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
        self._casters: dict[int, np.ndarray | None] = {}   # per light row: (T,) triangles that may cast
        self._raster = FaceRasterizer(tables, tri_vertices, options.size, device)
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
        if not rows:
            return
        t0 = time.perf_counter()
        self._plan(rows)
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

    def _used_vertices(self, s: Sample) -> np.ndarray:
        tris = self.tri_vertices[s.tri_visible] if len(s.tri_visible) else self.tri_vertices
        return s.positions[np.unique(tris.ravel())] if len(tris) else np.zeros((0, 3))

    def _local(self, j: int, s: Sample) -> np.ndarray:
        origin, axes = light_frame(s.lights[j])
        return (self._used_vertices(s) - origin) @ axes.T

    def _plan(self, rows: list[int]) -> None:
        o = self.options
        probes = [self.sample(u) for u in (0.0, 0.5, 1.0)]
        for j in rows:
            row = probes[1].lights[j]
            kind = int(row[0])
            locs = [self._local(j, s) for s in probes]
            allp = np.concatenate(locs)
            if len(allp) == 0:
                continue
            towards = allp.mean(axis=0)
            towards = towards / max(np.linalg.norm(towards), 1e-30) if np.linalg.norm(towards) > 0 else np.array([0, 0, -1.0])
            soft = kind in (RECT, DISK) or (kind == SPHERE and row[16] > 0)
            offsets = light_sample_offsets(row, o.light_samples if soft else 1, towards)
            pts = np.concatenate([allp - off for off in offsets]) if len(offsets) > 1 else allp
            faces = fit_faces(kind, pts, self.size)
            extent = float(np.abs(allp).max()) + 1.0
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
            warn_once("shadow-budget", f"shadow maps: {b} instants instead of {requested} to stay within "
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
            self._still[lay.row] = still_triangles([self.sample(u) for u in STILL_PROBES], lay.row, self.tri_vertices)
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

    def _render_direct(self, work: list[tuple[LightLayout, list[tuple[int, int, int, float]]]], maps: np.ndarray,
                       laid: TexelMajorLayout | None = None) -> None:
        """Render the lights' direct maps (per light, jobs (slot, face, light sample, time)) into
        maps, one map per pool thread as a single-core launch: a map's host-side setup overlaps the
        other threads' rasterizing, and no light waits for the last map of the one before. Still
        bases (one per light, face and sample) are rendered first, so no two threads render the
        same one. With `laid`, a face's instants render one after another and the thread that
        completes a face lays it out while the others render on."""
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
                for _slot, fi, m, u in jobs:
                    first.setdefault((fi, m), u)
                bases += [(lay, fi, m, u, still) for (fi, m), u in first.items()]
        map_threads(lambda b: self._base(b[0], b[1], b[2], self.sample(b[3]), b[4], single), bases, threads)

        def one(item: tuple[LightLayout, tuple[int, int, int, float]]) -> None:
            lay, (slot, fi, m, u) = item
            maps[slot] = self._direct_depth(lay, fi, m, u, single)
            if laid is not None:
                laid.rendered(slot)
        order = [(lay, job) for lay, jobs in work
                 for job in (sorted(jobs, key=lambda job: (job[2], job[1], job[3])) if laid is not None else jobs)]
        map_threads(one, order, threads)   # with `laid`, face by face
        self._add_time("shadow_render", time.perf_counter() - t0)

    def _key_times(self, lay: LightLayout) -> list[float]:
        """Key instants: open and close, bisected while the light-space motion between keys is
        more than a texel from linear (up to `keys` keys)."""
        keys = [0.0, 1.0]
        texel = self._texel_size(lay)
        while 2 * len(keys) - 1 <= self.options.keys:
            worst = 0.0
            for u0, u1 in zip(keys, keys[1:]):
                a, b, mid = (self._local(lay.row, self.sample(u)) for u in (u0, u1, 0.5 * (u0 + u1)))
                if a.shape == b.shape == mid.shape and len(a):
                    dev = np.linalg.norm(mid - 0.5 * (a + b), axis=1)
                    worst = max(worst, float((dev / texel(mid)).max()))
            if worst <= 1.0:
                break
            keys = sorted(set(keys) | {0.5 * (u0 + u1) for u0, u1 in zip(keys, keys[1:])})
        return keys

    def _texel_size(self, lay: LightLayout) -> Callable[[np.ndarray], np.ndarray]:
        """World size of a texel at light-local points (per point)."""
        face = lay.faces[0]
        w = (face.window[2] - face.window[0]) / self.size
        if face.ortho:
            return lambda p: np.full(len(p), w)
        return lambda p: np.maximum(np.linalg.norm(p, axis=1), 1e-12) * w

    def _key(self, lay: LightLayout, ki: int, key_time: float):
        """Key maps of a light (centre sample) at a key instant: per face (depth, tri, bary) numpy."""
        ident = (lay.row, ki)
        if ident not in self._keys:
            t0 = time.perf_counter()
            s = self.sample(key_time)
            out = []
            for face in lay.faces:
                a, t = self._face_transform(lay, face, self._centre(lay), s)
                d, tr, ba = self._raster.gather(a, t, face, s, self.threads, self._cast(lay, None))
                out.append((d.numpy().reshape(self.size, self.size), tr.numpy().reshape(self.size, self.size),
                            ba.numpy().reshape(self.size, self.size, 2)))
            self._keys[ident] = out
            self._key_dev[ident] = wp.array(np.stack([o[0] for o in out]), dtype=float, device=self.device)
            self._count("shadow_key_maps", len(lay.faces))
            self._add_time("shadow_render", time.perf_counter() - t0)
        return self._keys[ident], self._key_dev[ident]

    def _centre(self, lay: LightLayout) -> int:
        """The key maps' light position: the sample nearest the light's centre (its offset is
        applied; the warp accounts for the difference to every other sample)."""
        return int(np.argmin(np.linalg.norm(lay.offsets, axis=1)))

    # ------------------------------------------------------------------------------ warping
    def _key_mesh(self, lay: LightLayout, ident: tuple[int, int], fk: int) -> KeyMesh:
        """What a key face's warp needs whatever the target (cached): control points at every
        step-th texel with the surface they see, the mesh triangles that do not cross a depth
        discontinuity or two objects, and the texels of the cut cells."""
        cache_id = (ident, fk)
        if cache_id in self._meshes:
            return self._meshes[cache_id]
        kdepth, ktri, kbary = self._keys[ident][fk]
        kface = lay.faces[fk]
        s = self.size
        step = max(1, s // max(1, min(self.options.grid, s)))
        g_idx = np.unique(np.minimum(np.arange(0, s + step, step), s - 1))
        ng = len(g_idx)
        gy, gx = np.meshgrid(g_idx, g_idx, indexing="ij")
        ntri = ktri[gy, gx].ravel()
        kz = kdepth[gy, gx].ravel()
        valid = ntri >= 0
        obj = np.where(valid, self.tri_object[np.maximum(ntri, 0)], -1)
        texel_w = (kface.window[2] - kface.window[0]) / s
        tau = JUMP_CELLS * step * texel_w * (np.ones_like(kz) if kface.ortho else np.where(valid, kz, 0.0))
        i00 = (np.arange(ng - 1)[:, None] * ng + np.arange(ng - 1)[None, :]).ravel()
        corners = np.stack([i00, i00 + 1, i00 + ng + 1, i00 + ng], axis=1)          # (C, 4): 00 10 11 01
        tri_nodes = np.concatenate([corners[:, [0, 1, 2]], corners[:, [0, 2, 3]]])   # (2C, 3)
        good = valid[tri_nodes].all(axis=1) & (obj[tri_nodes] == obj[tri_nodes[:, :1]]).all(axis=1)
        zt = np.where(valid[tri_nodes], kz[tri_nodes], 0.0)
        good &= (zt.max(axis=1) - zt.min(axis=1)) <= tau[tri_nodes].min(axis=1)
        ncell = len(corners)
        cut = ~(good[:ncell] & good[ncell:]) & valid[corners].any(axis=1)
        # texels of cut cells (a cell spans its corner texels inclusive)
        cut_grid = cut.reshape(ng - 1, ng - 1)
        mask = np.zeros((s + step, s + step), bool)
        mask[:(ng - 1) * step, :(ng - 1) * step] = np.kron(cut_grid, np.ones((step, step), bool))
        mask[1:, :] |= mask[:-1, :].copy()
        mask[:, 1:] |= mask[:, :-1].copy()
        mask = mask[:s, :s] & (ktri >= 0)
        ty, tx = np.nonzero(mask)
        mesh = KeyMesh(
            node_tri=ntri, node_bary=kbary[gy, gx].reshape(-1, 2), node_depth=kz,
            node_src=np.stack([gx.ravel() + 0.5, gy.ravel() + 0.5], axis=1), tri_nodes=tri_nodes[good],
            texel_xy=np.stack([tx, ty], axis=1), texel_tri=ktri[ty, tx], texel_bary=kbary[ty, tx],
            texel_depth=kdepth[ty, tx])
        self._meshes[cache_id] = mesh
        return mesh

    def _warp_prims(self, lay: LightLayout, ident: tuple[int, int], target: Sample, a: np.ndarray,
                    t: np.ndarray, tface: Face):
        """Warped triangles from one key's faces into a target face: (src (P, 3, 2), dst (P, 3, 2),
        dz (P, 3), key face (P,)), and the number of control points that moved."""
        s = self.size
        proj = tface.projection(s)
        tv = self.tri_vertices
        srcs, dsts, dzs, keys = [], [], [], []
        num_cp = 0

        def motion(tri: np.ndarray, bary: np.ndarray):
            """Target texel coords (N, 2), depth (N,) and validity of key surface points."""
            wb, wc = bary[:, 0:1], bary[:, 1:2]
            v = tv[np.maximum(tri, 0)]
            p = (1 - wb - wc) * target.positions[v[:, 0]] + wb * target.positions[v[:, 1]] + wc * target.positions[v[:, 2]]
            q = p @ a.T + t
            depth = -q[:, 2]
            with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
                xy = proj.project(q)
                ok = np.isfinite(xy).all(axis=1) & (tri >= 0) & (np.abs(xy) < 4 * s).all(axis=1)
            if not tface.ortho:
                ok &= depth > tface.near
            return xy, depth, ok

        for fk in range(len(lay.faces)):
            km = self._key_mesh(lay, ident, fk)
            xy, depth, ok = motion(km.node_tri, km.node_bary)
            num_cp += int((km.node_tri >= 0).sum())
            tn = km.tri_nodes[ok[km.tri_nodes].all(axis=1)]
            if len(tn):
                srcs.append(km.node_src[tn])
                dsts.append(xy[tn])
                dzs.append((depth - km.node_depth)[tn])
                keys.append(np.full(len(tn), fk, np.int32))
            if len(km.texel_tri):   # cut cells: texels warp one by one with their own motion
                pxy, pdepth, pok = motion(km.texel_tri, km.texel_bary)
                txy = km.texel_xy[pok].astype(np.float64)
                shift = pxy[pok] - (txy + 0.5)
                pdz = (pdepth - km.texel_depth)[pok]
                c = np.stack([txy, txy + (1, 0), txy + (1, 1), txy + (0, 1)], axis=1)       # (n, 4, 2)
                for tri_c in ([0, 1, 2], [0, 2, 3]):
                    srcs.append(c[:, tri_c])
                    dsts.append(c[:, tri_c] + shift[:, None])
                    dzs.append(np.repeat(pdz[:, None], 3, axis=1))
                    keys.append(np.full(len(txy), fk, np.int32))
                num_cp += len(txy)
        cat = lambda xs, shape: np.concatenate(xs) if xs else np.zeros(shape)  # noqa: E731
        return (cat(srcs, (0, 3, 2)), cat(dsts, (0, 3, 2)), cat(dzs, (0, 3)), cat(keys, (0,)).astype(np.int32),
                num_cp)

    def _warp_face(self, lay: LightLayout, fi: int, m: int, u: float, keys: list[float]) -> np.ndarray:
        """(S, S) map of light sample m, face fi at shutter time u, warped from the bracketing keys."""
        s = self.size
        target = self.sample(u)
        tface = lay.faces[fi]
        a, t = self._face_transform(lay, tface, m, target)
        hi = int(np.searchsorted(keys, u, side="left"))
        lo = max(hi - 1, 0)
        hi = min(hi, len(keys) - 1)
        out = wp.full(s * s, wp.inf, dtype=float, device=self.device)
        proj = tface.projection(s)
        for ki in sorted({lo, hi}):
            _key, key_dev = self._key(lay, ki, keys[ki])
            t0 = time.perf_counter()
            src, dst, dz, kf, ncp = self._warp_prims(lay, (lay.row, ki), target, a, t, tface)
            self._count("shadow_control_points", ncp)
            boxes = np.concatenate([dst.min(axis=1), dst.max(axis=1)], axis=1) if len(dst) else np.zeros((0, 4))
            keep = np.isfinite(boxes).all(axis=1) & (boxes[:, 2] >= 0) & (boxes[:, 3] >= 0) & (boxes[:, 0] <= s) \
                & (boxes[:, 1] <= s)
            bins = bin_entries(proj, boxes, keep, WARP_TILE)
            dev = self.device
            args = [s, bins.tiles_x, WARP_TILE, key_dev,
                    device_array(src.reshape(-1, 2).astype(np.float32), wp.vec2, dev),
                    device_array(dst.reshape(-1, 2).astype(np.float32), wp.vec2, dev),
                    device_array(dz.astype(np.float32), wp.vec3, dev),
                    device_array(kf.astype(np.int32), int, dev),
                    device_array(bins.tile_offsets, int, dev),
                    device_array(bins.tile_entries.astype(np.int32), int, dev)]
            launch_pixels(warp_texels, s * s, lambda first, _n: args + [first, out], dev, self.threads)
            self._add_time("shadow_warp", time.perf_counter() - t0)
            self._warp_seconds_per_texel = (time.perf_counter() - t0) / (s * s)
        return out.numpy().reshape(s, s)

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
        texel_major (B > 1): each face laid out for spans of time as soon as it is complete."""
        t_start = time.perf_counter()
        s = self.size
        total = sum(len(lay.offsets) * len(lay.faces) for lay in self.layouts) * len(times)
        maps = np.empty((total, s, s), np.float32)
        faces = np.zeros((total, FACE_WIDTH), np.float32)
        info = np.full((max(self.num_lights, 1), 3), -1, np.int32)
        laid = TexelMajorLayout(maps, len(times)) if texel_major and len(times) > 1 else None
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
            for m in range(len(lay.offsets)):
                for u in times:
                    for fi, face in enumerate(lay.faces):
                        queued = keys is None and lay.warp is not None
                        if queued:
                            jobs.append((idx, fi, m, u))
                        elif keys is None:
                            t0 = time.perf_counter()
                            bases = self.counters.get("shadow_maps_still_base", 0)
                            maps[idx] = self._direct_depth(lay, fi, m, u)
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
                            maps[idx] = self._warp_face(lay, fi, m, u, keys)
                            self._count("shadow_maps_warped", 1)
                        if laid is not None and not queued:   # rendered (or warped) just now
                            laid.rendered(idx)
                        faces[idx, 0:9] = face.rotation.ravel()
                        faces[idx, 9:12] = lay.offsets[m]
                        faces[idx, 12:16] = face.window
                        faces[idx, 16] = 1.0 if face.ortho else 0.0
                        faces[idx, 17] = face.near if not face.ortho else -FAR
                        faces[idx, 18] = 1.0 if face.cube else 0.0
                        faces[idx, 19:22] = face_scales(face.window, s)
                        idx += 1
            direct_jobs.append((lay, jobs))
        self._render_direct(direct_jobs, maps, laid)
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
    rows = material_table[np.unique(tri_material)]
    return bool(((rows[:, 10] > 0.5) | (rows[:, 21] > 0.5) | (np.abs(rows[:, 0:3]).sum(axis=1) > 0)
                 | (np.abs(rows[:, 6:9]).sum(axis=1) > 0)).any())
