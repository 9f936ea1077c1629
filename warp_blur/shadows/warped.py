"""Shadow maps warped from a few key maps through a mesh of control points (the warped half of
shadows/maps.py's ShadowMaps, which renders the rest directly).

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

import time
from typing import Callable

import numpy as np
import warp as wp

from ..core.parallel import launch_pixels
from ..kernels.shadow_raster import warp_texels
from ..raster.binning import bin_entries
from ..raster.device_data import device_array
from .layout import Face, KeyMesh, LightLayout, Sample

#: cells whose key depths differ by more than this many cell widths are cut (depth discontinuity)
JUMP_CELLS = 8.0
#: tile size (texels) of the warped triangles' bins: small, since control-point cells are small
WARP_TILE = 8


class KeyWarping:
    """Key maps of a light and maps warped from them, for ShadowMaps (which holds the frame's
    samples, options, rasterizer and caches these methods use)."""

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
