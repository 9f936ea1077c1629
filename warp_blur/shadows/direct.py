"""Direct shadow maps: one face of a light rendered from the scene's triangles by the sharp
rasterizer's hit test (depth splatted per triangle, or depth, triangle and barycentrics gathered
per texel for warping keys), and the triangles that hold still in a light's frame (rendered once
into a base map that every instant's moving triangles are rendered over).
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ..core.parallel import launch_cheap, launch_pixels, launch_row_bands
from ..core.rows import all_corners
from ..kernels.shadow_raster import render_shadow_texels, splat_boxes, splat_shadow_depth
from ..raster.binning import TILE_SIZE, bin_entries, entry_pixel_bounds
from ..kernels.kernel_types import Geometry
from ..raster.device_data import TriangleTables, make_bins, make_geometry, make_view
from .layout import Face, Sample, light_frame
from .vertex_passes import face_positions, light_frame_changes

#: shutter instants at which a triangle must hold still to render once into a static base map
#: (the motion planner's probes; a vertex is still when it is the same at all of them)
STILL_PROBES = (0.0, 0.1234, 0.25, 0.5, 0.618, 0.75, 1.0)
#: light-local positions this close (relative to the scene's extent) at every probe are still:
#: a world-still point seen from a moving camera differs by the light table's float32 rounding
#: (~1e-6), far below a texel (1/size of the extent)
STILL_TOL = 1e-5


def still_triangles(probes: list[Sample], row: int, tri_vertices: np.ndarray, threads: int | None = None) -> np.ndarray:
    """(T,) bool: triangles that hold still in light `row`'s frame, the same (to STILL_TOL of the
    scene's extent) and equally visible at every probe. Under a light that holds still in the
    world these are the world-still triangles whatever the camera does: stillness is judged in
    the light's frame, where the maps are rigid, not in camera space. Each probe's light-frame
    change is one float64 kernel pass over bands of vertices (vertex_passes.py; NumPy's form, kept
    as the tests' oracle, made ~8 passes over every vertex a probe)."""
    ref = probes[0]
    still_t = np.ones(len(tri_vertices), bool)
    if any(p.positions.shape != ref.positions.shape for p in probes[1:]):
        return np.zeros(len(tri_vertices), bool)
    change, size = light_frame_changes(ref.positions, light_frame(ref.lights[row]),
                                       [(p.positions, light_frame(p.lights[row])) for p in probes[1:]], threads)
    for p in probes[1:]:
        if len(p.tri_visible) == len(still_t):
            still_t &= p.tri_visible == ref.tri_visible
    tol = STILL_TOL * (float(size.max(initial=0.0)) + 1.0)
    still_v = change <= tol
    return still_t & all_corners(still_v, tri_vertices) if len(tri_vertices) else still_t


class FaceRasterizer:
    """Renders S×S faces of the frame's triangles (tables and (T, 3) vertex indices) given a
    face transform (A (3, 3), t (3,): face-space q = A p + t of camera-space p)."""

    def __init__(self, tables: TriangleTables, tri_vertices: np.ndarray, size: int, device: str,
                 tri_object: np.ndarray | None = None) -> None:
        self.tables, self.tri_vertices, self.size, self.device = tables, tri_vertices, size, device
        self.no_flags = wp.zeros(0, dtype=wp.uint8, device=device)
        self.no_cull = wp.zeros(0, dtype=float, device=device)
        self.tri_object = tri_object
        #: (objects,) the sign of each closed opaque instance's volume over the frame (0: not
        #: closed, or not the same sign throughout), set by the frame's maps (cull_signs)
        self.object_sign: np.ndarray | None = None
        self._vertex_object: np.ndarray | None = None

    def cull_signs(self, positions: np.ndarray, instants: list[int], face: Face) -> wp.array:
        """(times * T,) per instant b of positions (times, V, 3), face space, and triangle t, row
        b T + t: the volume sign of t's closed instance where the light is outside it at b (every
        vertex of the instance in front of the face's near plane; a distant light is outside
        everything), else 0. Along any ray from a light outside a closed surface the nearest hit is
        a front face, so the splat leaves out the back faces (culling.hidden_back_faces' argument,
        the light as the eye): no texel changes. Empty when nothing is closed."""
        sign = self.object_sign
        if sign is None or not sign.any() or self.tri_object is None:
            return self.no_cull
        if self._vertex_object is None:
            vertex_object = np.full(max(positions.shape[1], int(self.tri_vertices.max(initial=-1)) + 1), -1, np.int64)
            vertex_object[self.tri_vertices.ravel()] = np.repeat(self.tri_object, 3)
            self._vertex_object = vertex_object
        num_tris = len(self.tri_vertices)
        out = np.zeros(positions.shape[0] * num_tris, np.float32)
        tri_sign = sign[self.tri_object]
        for b in set(instants):
            if face.ortho:
                out[b * num_tris:(b + 1) * num_tris] = tri_sign
                continue
            near = -positions[b, :len(self._vertex_object), 2] < face.near   # vertices not in front
            crossing = np.zeros(len(sign), bool)
            objects = self._vertex_object[:positions.shape[1]][near]
            crossing[objects[objects >= 0]] = True
            out[b * num_tris:(b + 1) * num_tris] = np.where(crossing[self.tri_object], 0.0, tri_sign)
        return wp.array(out, dtype=float, device=self.device)

    def _visible(self, s: Sample, subset: np.ndarray | None) -> np.ndarray:
        """(N,) int32: the triangles visible at sample s (of `subset`, a (T,) mask, when given)."""
        visible = s.tri_visible if len(s.tri_visible) else np.zeros(len(self.tri_vertices), bool)
        if subset is not None:
            visible = visible & subset
        return np.flatnonzero(visible).astype(np.int32)

    def scene(self, a: np.ndarray, t: np.ndarray, face: Face, s: Sample, subset: np.ndarray | None):
        """(view, geometry with one static entry per visible triangle, device tile bins) of the face
        at sample s, with the visible triangles (of `subset`, a (T,) mask, when given)."""
        q = s.positions @ a.T + t
        proj = face.projection(self.size)
        tris = self._visible(s, subset)
        k = np.zeros(len(tris), np.int32)
        geo = make_geometry(self.tables, q[None], None, tris, k, k)
        boxes, keep = entry_pixel_bounds(proj, q[None], self.tri_vertices, tris, k, k, 1.0)
        bins = bin_entries(proj, boxes, keep, TILE_SIZE)
        view = make_view(proj, 1, bins, TILE_SIZE)
        view.near = face.near
        return view, geo, make_bins(bins, self.device)

    def depth_over(self, a: np.ndarray, t: np.ndarray, face: Face, s: Sample, subset: np.ndarray | None,
                   base: np.ndarray | None, threads: int | None) -> np.ndarray:
        """Depth (S, S) of the visible triangles (of `subset`) rendered over `base` (the nearer
        wins; None: an empty map), each triangle splatted over its rows' spans (atomic min:
        order-free). Depth-only maps are splatted rather than gathered per texel: a texel then
        tests the triangles that cover it, not its tile's whole list; each triangle finds its own
        box in the kernel, so the host neither bounds nor bins."""
        proj = face.projection(self.size)
        tris = self._visible(s, subset)
        k = np.zeros(len(tris), np.int32)
        placed = face_positions([(a, t)], [s], [0], 1, self.device, threads)
        geo = make_geometry(self.tables, placed, None, tris, k, k)
        view = make_view(proj, 1, None, TILE_SIZE)
        view.near = face.near
        if base is None:
            depth = wp.full(self.size * self.size, wp.inf, dtype=float, device=self.device)
        else:
            depth = wp.array(base.ravel(), dtype=float, device=self.device)
        # (the cull test reads depths only for a perspective face with closed instances, in float64)
        reads_depths = not face.ortho and self.object_sign is not None and bool(self.object_sign.any())
        cull = self.cull_signs((s.positions @ a.T + t)[None] if reads_depths else placed.numpy(), [0], face)
        self._splat(view, geo, cull, 1, 1, depth, self.no_flags, self.no_flags, threads)
        return depth.numpy().reshape(self.size, self.size)

    def instants_geometry(self, transforms: list[tuple[np.ndarray, np.ndarray]], samples: list[Sample],
                          instants: list[int], times: int, subset: np.ndarray | None,
                          face: Face) -> tuple[Geometry, wp.array] | None:
        """Geometry of a face at several instants for splat_shadow_depth with stride `times`:
        positions (times, V, 3) in face space (instant b = instants[i] from transforms[i] (A, t)
        and samples[i]; others unused), one static entry per triangle visible at an instant (of
        `subset`) with entry_k0 = entry_k1 = its instant, and face's cull_signs. None when no
        triangle is visible."""
        placed = face_positions(transforms, samples, instants, times, self.device)
        pos = placed.numpy().reshape(times, -1, 3)   # (a view of the same memory: the cull test reads depths)
        tris, ks = [], []
        for s, b in zip(samples, instants):
            tri = self._visible(s, subset)
            tris.append(tri)
            ks.append(np.full(len(tri), b, np.int32))
        tri = np.concatenate(tris) if tris else np.zeros(0, np.int32)
        if len(tri) == 0:
            return None
        k = np.concatenate(ks)
        return make_geometry(self.tables, placed, None, tri, k, k), self.cull_signs(pos, instants, face)

    def splat_instants(self, face: Face, prepared: tuple[Geometry, wp.array], times: int, target: wp.array,
                       touched: wp.array, threads: int | None, occupied: wp.array | None = None,
                       block: int = 1) -> None:
        """Splat instants_geometry's entries (geometry and cull signs) into target (S * S * times,):
        texel-major, each texel's `times` depths side by side, over what it holds (the nearer depth
        wins); touched (S * S,) uint8 gets 1 where an entry covers a texel at some instant, and
        occupied (ceil(S / block)²,) uint8, when given, 1 at the blocks where an entry writes."""
        occupied = self.no_flags if occupied is None else occupied
        geo, cull = prepared
        view = make_view(face.projection(self.size), 1, None, TILE_SIZE)
        view.near = face.near
        self._splat(view, geo, cull, times, block, target, touched, occupied, threads)

    def _splat(self, view, geo: Geometry, cull: wp.array, stride: int, block: int, target: wp.array,
               touched: wp.array, occupied: wp.array, threads: int | None) -> None:
        """splat_shadow_depth of geo's entries into target over row bands in parallel, each
        entry's texel box found once first (splat_boxes, over bands of entries)."""
        entries = geo.entry_tri.shape[0]
        if entries == 0:
            return
        boxes = wp.empty(entries, dtype=wp.vec4i, device=self.device)
        num_tris = len(self.tri_vertices)
        launch_cheap(splat_boxes, entries, lambda first, _n: [view, geo, cull, num_tris, first, boxes], self.device,
                     threads)
        launch_row_bands(splat_shadow_depth, entries, self.size,
                         lambda y0, y1: [view, geo, boxes, y0, y1, stride, block, target, touched, occupied],
                         self.device, threads)

    def gather(self, a: np.ndarray, t: np.ndarray, face: Face, s: Sample, threads: int | None,
               subset: np.ndarray | None = None):
        """Depth (S*S,), triangle (S*S,) and barycentrics (S*S, 2) warp arrays of the face (a warp
        key: each texel knows the surface point it sees), of the visible triangles (of `subset`)."""
        view, geo, b = self.scene(a, t, face, s, subset)
        n = self.size * self.size
        depth = wp.empty(n, dtype=float, device=self.device)
        tri = wp.empty(n, dtype=int, device=self.device)
        bary = wp.empty(n, dtype=wp.vec2, device=self.device)
        launch_pixels(render_shadow_texels, n, lambda first, _n: [view, geo, b, first, depth, tri, bary],
                      self.device, threads)
        return depth, tri, bary
