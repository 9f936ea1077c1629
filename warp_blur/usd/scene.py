"""USD -> NumPy: static topology read once per frame, camera-space snapshots at any shutter time.

pxr is read under `usd/` (and for a prim's motion sample count in the motion plan, and by
`tools/info.py`). Positions are composed in float64 and made camera-relative (cam_from_local =
local_to_world @ world_to_cam) before kernels see them as float32, so scenes far from the origin
keep their precision. Materials come from a table the Renderer may keep across frames
(material_cache.py).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
from pxr import Usd, UsdGeom, UsdShade

from ..core.affine import camera_from_world
from ..core.errors import InvalidGeometryError
from .dome import dome_map
from .lights import dome_radiance, find_lights, headlight_table, light_table
from ..core.log import warn_once
from .materials import CODE_CORNER_OPACITY, MaterialTable
from .curves import curves_unit_fields
from .points import derived_points_fn, points_unit_fields
from .normals import authored_normals_fn, split_normals_fn, transform_normals, vertex_normals
from .subdivision import mesh_refinement, refined_surface_primvars, refined_triangles, screen_level, stage_level
from .skinning import Skins, skinned_points_fn
from .stage import Shutter
from .primvars import corner_primvar, grey_corners
from .tessellate import (SPHERE_LEVEL_MAX, gprim_number, sphere_levels, sphere_radius_px, tessellate_gprim,
                         triangulate_corners)
from .instancer import IMPLICIT, add_instancer_units
from .values import UnreadableValue, array_value, value_count
from .units import (FLAG_DOUBLE_SIDED, FLAG_SMOOTH, GeomUnit, SmallUnitGroup, UnitRows, held_points,
                    prim_transform_fn, small_unit_groups)

_SILENT_TYPES = {"Xform", "Scope", "Camera", "", "Material", "Shader", "NodeGraph", "GeomSubset",
                 "RenderSettings", "RenderProduct", "RenderVar", "SkelRoot", "Skeleton", "SkelAnimation"}


@dataclass
class Snapshot:
    """The scene at one shutter instant, in camera space.

    positions: (V, 3) float64 camera-space vertices; normals: (V, 3) float32 smooth vertex normals;
    tri_visible: (T,) bool; lights: (NL, LIGHT_WIDTH) float32; cam_from_world: (4, 4) float64.
    """

    time: float
    positions: np.ndarray
    normals: np.ndarray
    tri_visible: np.ndarray
    lights: np.ndarray
    cam_from_world: np.ndarray
    fraction: float | None = None   # the shutter fraction it was taken at (FrameContext.snapshot)


class Scene:
    """Renderable geometry, materials and lights of a stage for one frame.

    Static data (topology, materials) is read once; `snapshot(time)` samples what moves.
    """

    def __init__(self, stage: Usd.Stage, camera: UsdGeom.Camera, frame: float, shutter: Shutter,
                 skip_invalid: bool = False, proj=None, materials: MaterialTable | None = None,
                 kept_units=None, sphere_error_px: float | None = None) -> None:
        self.stage = stage
        self.proj = proj   # the image's Projection when known: subdivision levels follow screen size
        self.sphere_error_px = sphere_error_px   # spheres' facet error on screen (tessellate.sphere_levels)
        self.camera = camera
        self.frame = frame
        self.shutter = shutter
        self.skip_invalid = skip_invalid
        # a table kept from an earlier frame where nothing it read can change (material_cache.py)
        self.materials = materials if materials is not None else MaterialTable(frame)
        self.kept_units = kept_units   # a UnitCache: units kept from earlier frames (unit_cache.py)
        self.units_reused = 0
        self._levels: dict[str, int] = {}   # subdivision meshes' levels this frame (_mesh_level)
        self.units: list[GeomUnit] = []
        self._xf_caches: dict[float, UsdGeom.XformCache] = {}
        self._transform_verdicts: dict = {}   # prim path -> its transform may vary over time
        self._cam_memo: tuple[bytes, np.ndarray] | None = None   # (camera-to-world bytes, its inverse)
        self._skins = Skins()
        self._groups: list | None = None          # _small_unit_groups, found on first use
        self._dropped: set[int] = set()           # units dropped as invalid at a snapshot (skip_invalid)
        self._snapshots_taken = 0
        self._unit_grouped = np.zeros(0, bool)
        self._collect()
        self.light_prims, dome = find_lights(stage)
        self.dome = dome_radiance(dome, frame)
        # a textured dome: its map (background and ambient); self.dome is then the map's mean
        self.dome_map = dome_map(dome.prim if dome is not None else None, frame, self.dome, self.materials.textures)
        if self.dome_map is not None:
            self.dome = self.dome_map.mean
        self.has_dome = dome is not None
        self.headlight = not self.light_prims and dome is None
        self._build_tables()

    # ----------------------------------------------------------------------------- collection
    def _xf_cache(self, time: float) -> UsdGeom.XformCache:
        cache = self._xf_caches.get(time)
        if cache is None:
            if len(self._xf_caches) > 64:
                self._xf_caches.clear()
            cache = self._xf_caches[time] = UsdGeom.XformCache(Usd.TimeCode(time))
        return cache

    def _invalid(self, path: str, problem: str) -> bool:
        """Handle invalid geometry: raise, or warn and tell the caller to drop the prim."""
        if not self.skip_invalid:
            raise InvalidGeometryError(path, problem)
        warn_once(f"invalid:{path}", f"dropping {path}: {problem}")
        return True

    def _collect(self) -> None:
        t = Usd.TimeCode(self.frame)
        it = iter(Usd.PrimRange(self.stage.GetPseudoRoot(), Usd.TraverseInstanceProxies(Usd.PrimDefaultPredicate)))
        for prim in it:
            if not prim.IsA(UsdGeom.Imageable):
                if prim.GetTypeName() not in _SILENT_TYPES and not prim.IsPseudoRoot():
                    pass
                continue
            purpose = UsdGeom.Imageable(prim).ComputePurpose()
            if purpose in (UsdGeom.Tokens.proxy, UsdGeom.Tokens.guide):
                it.PruneChildren()
                continue
            if prim.IsA(UsdGeom.PointInstancer):
                self._read_checked(prim, lambda: add_instancer_units(self, prim, t))
                it.PruneChildren()
            elif prim.IsA(UsdGeom.Mesh):
                self._read_checked(prim, lambda: self._read_or_reuse(prim, t, self._add_mesh))
            elif any(prim.IsA(c) for c in IMPLICIT):
                self._read_checked(prim, lambda: self._read_or_reuse(prim, t, self._add_gprim))
            elif prim.IsA(UsdGeom.Points):     # camera-facing discs
                self._read_checked(prim, lambda: self._add_fields(points_unit_fields(self, prim, t)))
            elif prim.IsA(UsdGeom.BasisCurves):  # camera-facing ribbons
                self._read_checked(prim, lambda: self._add_fields(curves_unit_fields(self, prim, t)))
            elif prim.IsA(UsdGeom.Gprim) or prim.GetTypeName() not in _SILENT_TYPES and not _is_light(prim):
                warn_once(f"unsupported:{prim.GetPath()}",
                          f"{prim.GetPath()}: prim type {prim.GetTypeName()} is not rendered")

    def _read_checked(self, prim: Usd.Prim, read: Callable[[], None]) -> None:
        """read() the prim's units; one of its values that is no array of numbers (values.py) makes
        it invalid geometry: an error, or (--skip-invalid) dropped with what it had added."""
        n = len(self.units)
        try:
            read()
        except UnreadableValue as exc:
            del self.units[n:]
            self._invalid(str(prim.GetPath()), str(exc))

    def _read_or_reuse(self, prim: Usd.Prim, t: Usd.TimeCode, read) -> None:
        """The prim's unit as kept from an earlier frame (unit_cache.py), else read(prim, t) and
        offer what it added to the cache."""
        if self.kept_units is None or self._skins.find(prim) is not None:   # a skinned mesh is never kept
            read(prim, t)
            return
        if read == self._add_mesh:
            level = self._refinement_level(prim, t)
        else:
            level = self._sphere_level(prim) if prim.IsA(UsdGeom.Sphere) else None
        kept = self.kept_units.get(prim, self.materials, level)
        if kept is not None:
            self.units.append(kept)
            self.units_reused += 1
            return
        n = len(self.units)
        read(prim, t)
        if len(self.units) == n + 1:
            self.kept_units.keep(prim, self.units[-1], self.materials, level)

    def _refinement_level(self, prim: Usd.Prim, t: Usd.TimeCode) -> int | None:
        """A subdivision mesh's Catmull-Clark level this frame, found before its read (its size on
        screen decides; units are kept per level), None for a polygon mesh."""
        if UsdGeom.Mesh(prim).GetSubdivisionSchemeAttr().Get(t) in (None, UsdGeom.Tokens.none):
            return None
        try:
            return self._mesh_level(prim, self._points_fn(prim, value_count(UsdGeom.Mesh(prim).GetPointsAttr(), t)))
        except InvalidGeometryError:   # read (and named, or dropped) by _add_mesh
            return None

    def _mesh_topology(self, prim: Usd.Prim, t: Usd.TimeCode):
        mesh = UsdGeom.Mesh(prim)
        counts = array_value(mesh.GetFaceVertexCountsAttr(), t, np.int64)
        indices = array_value(mesh.GetFaceVertexIndicesAttr(), t, np.int64)
        holes = array_value(mesh.GetHoleIndicesAttr(), t, np.int64)
        left = mesh.GetOrientationAttr().Get(t) == UsdGeom.Tokens.leftHanded
        npts = value_count(mesh.GetPointsAttr(), t)
        path = str(prim.GetPath())
        bad = indices[(indices < 0) | (indices >= npts)]
        problem = (f"negative faceVertexCount {int(counts.min())}" if len(counts) and counts.min() < 0 else
                   "faceVertexCounts do not add up to faceVertexIndices" if counts.sum() != len(indices) else
                   f"face index {int(bad[0])} out of range (mesh has {npts} points)" if len(bad) else None)
        if problem is not None:
            return None if self._invalid(path, problem) else None
        tris, face_of_tri, corners = triangulate_corners(counts, indices, holes, left)
        scheme = mesh.GetSubdivisionSchemeAttr().Get(t)
        smooth = scheme not in (None, UsdGeom.Tokens.none)
        return tris, face_of_tri, corners, npts, smooth

    def _surface_primvars(self, prim: Usd.Prim, t: Usd.TimeCode, material: int, tris: np.ndarray,
                          face_of_tri: np.ndarray, corners: np.ndarray | None):
        """(corner colours (T, 3, 3), corner texture coordinates (T, 3, 2) or None, corner
        opacities (T, 3) or None) that the prim's material reads (its colour primvar, displayColor
        by default; its `st`; its opacity primvar, displayOpacity by default)."""
        reads = self.materials.reads[material]
        opacity = None
        if reads.opacity:
            values = corner_primvar(prim, reads.opacity, t, tris, face_of_tri, corners, 1)
            opacity = None if values is None else np.clip(values[..., 0], 0.0, 1.0)
        colors = None
        if reads.color:
            colors = corner_primvar(prim, reads.color, t, tris, face_of_tri, corners, 3)
        if colors is None:
            colors = grey_corners(len(tris))
        uvs = None
        if reads.st:
            uvs = corner_primvar(prim, reads.st, t, tris, face_of_tri, corners, 2)
            if uvs is None:
                warn_once(f"st:{prim.GetPath()}", f"{prim.GetPath()}: its material's textures read primvar "
                                                  f"'{reads.st}', which it does not have; texturing at (0, 0)")
                uvs = np.zeros((len(tris), 3, 2), np.float32)
        return colors, uvs, opacity

    def _points_fn(self, prim: Usd.Prim, npts: int) -> Callable[[float], np.ndarray]:
        """Local points at a time: USD's interpolation, velocities/accelerations applied by USD."""
        pb = UsdGeom.PointBased(prim)
        attr = pb.GetPointsAttr()
        has_vel = pb.GetVelocitiesAttr().HasAuthoredValue()
        path = str(prim.GetPath())
        base = self.frame
        static = not attr.ValueMightBeTimeVarying() and not has_vel
        cached: dict[str, np.ndarray] = {}

        def points_at(time: float) -> np.ndarray:
            if static and "p" in cached:
                return cached["p"]
            pts = None
            if has_vel:
                pts = pb.ComputePointsAtTime(Usd.TimeCode(time), Usd.TimeCode(base))
            if pts is None or len(pts) != npts:
                pts = attr.Get(Usd.TimeCode(time))
            arr = np.asarray(pts, np.float64).reshape(-1, 3) if pts is not None else np.zeros((0, 3))
            if len(arr) != npts:
                warn_once(f"ptcount:{path}", f"{path}: point count changes over time; holding the frame's points")
                arr = np.asarray(attr.Get(Usd.TimeCode(base)), np.float64).reshape(-1, 3)
            if not np.isfinite(arr).all():
                raise InvalidGeometryError(path, f"non-finite points at time {time}")
            if static:
                cached["p"] = arr
            return arr

        points_at.held = static   # one array at every time (SmallUnitGroup keeps it for the frame)
        return points_at

    def _valid_points_fn(self, prim: Usd.Prim, npts: int) -> Callable[[float], np.ndarray] | None:
        """_points_fn checked at the frame time: None when its points are not finite and the prim
        is dropped (--skip-invalid); an InvalidGeometryError naming it otherwise."""
        points_at = self._points_fn(prim, npts)
        try:
            points_at(self.frame)
        except InvalidGeometryError:
            if self._invalid(str(prim.GetPath()), "non-finite points"):
                return None
        return points_at

    def _mesh_level(self, prim: Usd.Prim, points_at: Callable[[float], np.ndarray]) -> int:
        """The stage's budget level (found once a frame), lowered to what the mesh's size on screen
        needs (if known); kept per prim for the frame (self._levels)."""
        path = str(prim.GetPath())
        if path not in self._levels:
            if not hasattr(self, "_subdivision_level"):
                self._subdivision_level = stage_level(self.stage, Usd.TimeCode(self.frame))
            level = self._subdivision_level
            if self.proj is not None and level > 1:
                to_cam = np.array(self._xf_cache(self.frame).GetLocalToWorldTransform(prim)) @ self.cam_from_world(self.frame)
                level = screen_level(self.proj, points_at(self.frame), to_cam, UsdGeom.Mesh(prim), self.frame, level)
            self._levels[path] = level
        return self._levels[path]

    def _prim_transform_fn(self, prim: Usd.Prim):
        """transforms_at of a prim (units.prim_transform_fn), the scene's verdicts shared."""
        return prim_transform_fn(prim, self._transform_verdicts)

    def _common(self, prim: Usd.Prim, t: Usd.TimeCode) -> tuple[int, int, float]:
        gprim = UsdGeom.Gprim(prim)
        flags = FLAG_DOUBLE_SIDED if gprim.GetDoubleSidedAttr().Get(t) else 0
        blur = UsdGeom.MotionAPI(prim).ComputeMotionBlurScale(t) if hasattr(UsdGeom, "MotionAPI") else 1.0
        return self.materials.index_for_prim(prim), flags, float(blur)

    def _add_mesh(self, prim: Usd.Prim, t: Usd.TimeCode) -> None:
        topo = self._mesh_topology(prim, t)
        if topo is None:
            return
        tris, face_of_tri, corners, npts, smooth = topo
        path = str(prim.GetPath())
        skin = self._skins.find(prim)
        points_at = skinned_points_fn(prim, npts, skin) if skin else self._points_fn(prim, npts)
        # skinned points are in skeleton space: the mesh's own transform is ignored (UsdSkel rules)
        xform_prim = skin[2] if skin else prim
        try:
            points_at(self.frame)
        except InvalidGeometryError:
            if self._invalid(path, "non-finite points"):
                return
        if len(tris) == 0:
            return
        material, flags, blur = self._common(prim, t)
        flags |= FLAG_SMOOTH if smooth else 0
        refined = mesh_refinement(UsdGeom.Mesh(prim), t, npts, self._mesh_level(prim, points_at)) \
            if smooth and not skin else None
        if refined is not None:    # Catmull-Clark levels instead of the cage (subdivision.py)
            ref, counts, indices = refined
            tris, face_of_tri, corner_weights = refined_triangles(ref)
            points_at = derived_points_fn(points_at, ref.stencil.__matmul__)
            npts = ref.stencil.shape[0]
        authored = refined is None and not smooth and not skin
        normals_at = authored_normals_fn(prim, t, npts) if authored else None
        split = split_normals_fn(prim, t, npts) if authored and normals_at is None else None
        if normals_at is not None or split is not None:
            flags |= FLAG_SMOOTH
        tri_materials = self.materials.subset_materials(prim, t, material, face_of_tri)
        if refined is not None:
            colors, uvs, opacity = refined_surface_primvars(prim, t, self.materials.reads[material], counts,
                                                            indices, face_of_tri, corner_weights)
            colors = colors if colors is not None else grey_corners(len(tris))
        else:
            colors, uvs, opacity = self._surface_primvars(prim, t, material, tris, face_of_tri, corners)
        if tri_materials is not None:   # each subset's triangles read what their own material reads
            uvs = uvs if uvs is not None else np.zeros((len(tris), 3, 2), np.float32)
            for m in np.unique(tri_materials[tri_materials != material]):
                c_m, uv_m, op_m = self._surface_primvars(prim, t, int(m), tris, face_of_tri, corners)
                rows = tri_materials == m
                colors[rows] = c_m[rows]
                if uv_m is not None:
                    uvs[rows] = uv_m[rows]
                if op_m is not None or opacity is not None:
                    opacity = opacity if opacity is not None else np.ones((len(tris), 3), np.float32)
                    opacity[rows] = op_m[rows] if op_m is not None else 1.0
        if split is not None and corners is not None:   # hard-edged faceVarying normals (normals.py)
            source, point_of_corner, normals_at = split
            tris = point_of_corner[corners].astype(tris.dtype)
            points_at = derived_points_fn(points_at, lambda p, s=source: p[s])
            npts = len(source)
        self.units.append(GeomUnit(
            path=path, prim=prim, local_tris=tris, num_points=npts, points_at=points_at,
            transforms_at=self._prim_transform_fn(xform_prim), num_instances=1,
            corner_colors=colors, corner_uvs=uvs, material=material,
            flags=flags, blur_scale=blur, visibility_prims=[prim], tri_materials=tri_materials,
            normals_at=normals_at, corner_opacity=opacity))

    def _sphere_level(self, prim: Usd.Prim) -> int:
        """An implicit sphere's icosphere level this frame (tessellate.sphere_levels), from its size
        on screen at the frame time when the image's projection is known; kept per prim for the
        frame (self._levels), so every shutter time sees the same triangles."""
        path = str(prim.GetPath())
        if path not in self._levels:
            level = SPHERE_LEVEL_MAX
            if self.proj is not None:
                to_cam = np.array(self._xf_cache(self.frame).GetLocalToWorldTransform(prim)) \
                    @ self.cam_from_world(self.frame)
                radius = gprim_number(UsdGeom.Sphere(prim).GetRadiusAttr(), Usd.TimeCode(self.frame))
                level = int(sphere_levels(sphere_radius_px(self.proj, to_cam[None], radius), self.sphere_error_px)[0])
            self._levels[path] = level
        return self._levels[path]

    def _add_gprim(self, prim: Usd.Prim, t: Usd.TimeCode) -> None:
        level = self._sphere_level(prim) if prim.IsA(UsdGeom.Sphere) else SPHERE_LEVEL_MAX
        out = tessellate_gprim(prim, t, level)
        if out is None:
            return
        pts, tris, smooth, face_of_tri, corners = out
        material, flags, blur = self._common(prim, t)
        flags |= FLAG_SMOOTH if smooth else 0
        colors, uvs, opacity = self._surface_primvars(prim, t, material, tris, face_of_tri, corners)
        self.units.append(GeomUnit(
            path=str(prim.GetPath()), prim=prim, local_tris=tris, num_points=len(pts),
            points_at=held_points(pts), transforms_at=self._prim_transform_fn(prim), num_instances=1,
            corner_colors=colors, corner_uvs=uvs, material=material, corner_opacity=opacity,
            flags=flags, blur_scale=blur, visibility_prims=[prim]))

    def _add_fields(self, fields: dict | None) -> None:
        """A unit whose fields points.py or curves.py built: double-sided (seen from either side)."""
        if fields:
            self.units.append(GeomUnit(**{**fields, "flags": fields["flags"] | FLAG_DOUBLE_SIDED}))

    # ----------------------------------------------------------------------------- tables
    def _build_tables(self) -> None:
        visibility_memo: dict = {}   # units under one parent ask about its visibility once
        for u in self.units:
            u.visibility_memo = visibility_memo
        rows = None
        if self.kept_units is not None and self.units_reused == len(self.units):
            rows = self.kept_units.rows_for(self.units)   # every unit kept: their rows too
        if rows is None:
            rows = UnitRows.of(self.units, self.frame)
            if self.kept_units is not None and self.units_reused == len(self.units):
                self.kept_units.keep_rows(self.units, rows)
        self.unit_vertex_offsets, self.num_vertices = rows.vertex_offsets, rows.num_vertices
        self.tri_vertices = rows.tri_vertices
        self.corner_colors = rows.corner_colors   # (3T, 3) corner 3t + k of triangle t
        self.corner_uvs = rows.corner_uvs         # (3T, 2)
        self.textured = rows.textured
        self.tri_material, self.tri_flags = rows.tri_material, rows.tri_flags
        self.tri_unit = rows.tri_unit
        self.tri_object = rows.tri_object   # (T,) prim instance of each triangle
        self.material_table = self.materials.array()
        cut = self.materials.cutouts()
        # (T, 3) opacity test per triangle (kernels/cutout.py), or None when every material is opaque;
        # (T,) triangles of fractional opacity (present at a fraction of each pixel's time samples);
        # (T, 3) corner opacities from a primvar (displayOpacity) where a material reads one, else 1
        alpha = rows.corner_alpha
        tri_cut = cut[self.tri_material] if len(self.tri_material) else np.zeros((0, 3), np.float32)
        self.tri_fractional = self.materials.fractional()[self.tri_material] if len(self.tri_material) \
            else np.zeros(0, bool)
        read = ~np.isnan(alpha[:, 0])
        primvar_test = np.zeros(len(read), bool)
        if read.any():   # (a frame of a million triangles without an opacity primvar skips these passes)
            alpha = np.where(read[:, None], alpha, 1.0).astype(np.float32)
            threshold = tri_cut[:, 1]
            primvar_test = read & ((threshold > 0) | (alpha.min(axis=1) < 1.0))
        if primvar_test.any():
            tri_cut = tri_cut.copy()
            tri_cut[primvar_test, 0] = CODE_CORNER_OPACITY
            self.tri_fractional = np.where(read, primvar_test & (threshold <= 0), self.tri_fractional)
        self.tri_cutout = tri_cut if (tri_cut[:, 0] != -1).any() else None
        self.tri_alpha = alpha if primvar_test.any() else None
        self.any_fractional = bool(self.tri_fractional.any())
        self.any_smooth = bool((self.tri_flags & FLAG_SMOOTH).any())
        # (T,) triangles of closed, opaque surfaces (raster/culling.py drops their hidden back faces)
        opaque = tri_cut[:, 0] == -1 if len(tri_cut) else np.zeros(0, bool)
        self.tri_closed = rows.closed_unit[self.tri_unit] & opaque if len(self.tri_unit) else np.zeros(0, bool)
        if self.tri_closed.any():
            unit_open = np.bincount(self.tri_unit[~self.tri_closed], minlength=len(self.units)) > 0
            self.tri_closed &= ~unit_open[self.tri_unit]     # one see-through triangle opens its prim

    @property
    def num_triangles(self) -> int:
        return len(self.tri_vertices)

    # ----------------------------------------------------------------------------- sampling
    def cam_from_world(self, time: float) -> np.ndarray:
        """(4, 4) float64 world -> camera matrix (row vectors) at a shutter time."""
        cam_to_world = np.array(self._xf_cache(time).GetLocalToWorldTransform(self.camera.GetPrim()), np.float64)
        key = cam_to_world.tobytes()
        if self._cam_memo is None or self._cam_memo[0] != key:   # a camera that holds still: inverted once
            self._cam_memo = (key, camera_from_world(cam_to_world, str(self.camera.GetPath()), time))
        return self._cam_memo[1].copy()

    def vertex_normals(self, positions: np.ndarray) -> np.ndarray:
        """(V, 3) float32 smooth vertex normals of the scene's triangles at positions (V, 3)."""
        return vertex_normals(positions, self.tri_vertices)

    def shading_normals(self, positions: np.ndarray, time: float) -> np.ndarray:
        """(V, 3) float32 camera-space shading normals at shutter time `time`: smooth vertex normals
        of `positions`, replaced by the authored ones where a mesh has them (normals.py)."""
        normals = self.vertex_normals(positions)
        authored = [(ui, u) for ui, u in enumerate(self.units) if u.normals_at is not None]
        if authored:
            normals = normals.copy()
            cam_from_world = self.cam_from_world(time)
            for ui, u in authored:
                t_prim = self.frame + (time - self.frame) * u.blur_scale
                m = u.transforms_at(t_prim, self._xf_cache(t_prim)) @ cam_from_world[None]
                o = self.unit_vertex_offsets[ui]
                normals[o:o + u.num_points * u.num_instances] = transform_normals(u.normals_at(t_prim), m)
        return normals

    def _small_unit_groups(self) -> list[SmallUnitGroup]:
        if self._groups is None:
            self._groups = small_unit_groups(self.units, self.unit_vertex_offsets, self.frame,
                                             (self.shutter.open, self.shutter.close), self._transform_verdicts)
            self._unit_grouped = np.zeros(len(self.units), bool)
            for g in self._groups:
                self._unit_grouped[g.units] = True
        return self._groups

    def snapshot(self, time: float, with_normals: bool = True) -> Snapshot:
        """The scene at USD time `time` (within the shutter), in camera space (without vertex
        normals when with_normals is False: a probe that only compares positions)."""
        cam_from_world = self.cam_from_world(time)
        positions = np.zeros((self.num_vertices, 3), np.float64)
        unit_visible = np.ones(len(self.units), bool)
        for g in self._small_unit_groups():   # many small prims: one batched transform
            t_prim = self.frame + (time - self.frame) * g.blur_scale
            g.place(self.units, t_prim, self._xf_cache(t_prim), cam_from_world, positions, unit_visible)
        for ui, u in enumerate(self.units):
            if self._unit_grouped[ui]:
                continue
            t_prim = self.frame + (time - self.frame) * u.blur_scale
            cache = self._xf_cache(t_prim)
            pts = u.points_at(t_prim)
            m = u.transforms_at(t_prim, cache) @ cam_from_world[None]       # (I, 4, 4) cam_from_local
            p = pts @ m[:, :3, :3] + m[:, None, 3, :3]    # (I, n, 3): batched matmul, far faster than einsum
            o = self.unit_vertex_offsets[ui]
            positions[o:o + u.num_points * u.num_instances] = p.reshape(-1, 3)
            unit_visible[ui] = u.visible_at(t_prim)
        if self._dropped or not np.isfinite(positions).all():
            self._drop_non_finite(positions, unit_visible, time)
        normals = (self.shading_normals(positions, time) if self.any_smooth and with_normals
                   else np.zeros((0, 3), np.float32))
        if self.headlight:
            lights = headlight_table()
        else:
            lights = light_table(self.light_prims, time, cam_from_world, self._xf_cache(time))
        self._snapshots_taken += 1
        return Snapshot(time=time, positions=positions, normals=normals,
                        tri_visible=unit_visible[self.tri_unit] if len(self.units) else np.zeros(0, bool),
                        lights=lights, cam_from_world=cam_from_world)


    def _drop_non_finite(self, positions: np.ndarray, unit_visible: np.ndarray, time: float) -> None:
        """Units whose transformed points are not finite at `time`: an InvalidGeometryError naming
        the first, or with skip_invalid each dropped with a warning: hidden at every snapshot (its
        points set to the eye: finite). A unit first found so after the frame's first snapshot
        raises UnitsDroppedMidFrame once marked: earlier snapshots showed it, so the frame is to
        be rendered again (Renderer.render does) with it hidden throughout."""
        new = False
        for ui, u in enumerate(self.units):
            rows = slice(self.unit_vertex_offsets[ui], self.unit_vertex_offsets[ui] + u.num_points * u.num_instances)
            if ui not in self._dropped and not np.isfinite(positions[rows]).all():
                if self._invalid(u.path, f"non-finite transformed points at time {time}"):
                    self._dropped.add(ui)
                    new = True
            if ui in self._dropped:
                positions[rows] = 0.0
                unit_visible[ui] = False
        if new and self._snapshots_taken > 0:
            raise UnitsDroppedMidFrame()


class UnitsDroppedMidFrame(Exception):
    """Raised by Scene.snapshot when skip_invalid drops a unit that earlier snapshots of the frame
    showed: the frame is rendered again with the unit hidden at every time (not a user error)."""


def _is_light(prim: Usd.Prim) -> bool:
    from pxr import UsdLux
    return prim.HasAPI(UsdLux.LightAPI) or prim.IsA(UsdShade.Material)
