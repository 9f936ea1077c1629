"""A scene's renderable units (GeomUnit: a prim, or a PointInstancer prototype's mesh with all
its instances), and the groups of small ones that snapshots place in camera space together: the
per-prim NumPy calls cost more than their arithmetic where a stage has dozens of quads
(deep_overlap: 48 prims, 1.5 ms a snapshot, ~0.7 ms of it per-prim overhead; a frame's motion plan
takes 34 to 129 snapshots)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np
from pxr import Sdf, Usd, UsdGeom

from .stage import prims_visible, transform_may_vary, visibility_varies
from .xform_ops import LinearTransforms


#: GeomUnit.flags bits: seen from both sides; shaded with interpolated vertex normals
FLAG_DOUBLE_SIDED = 1
FLAG_SMOOTH = 2


def prototype_unit_name(instancer: str, proto_path: Sdf.Path, sub_path: Sdf.Path) -> str:
    """A readable name for a PointInstancer prototype's mesh: `/World/Ring (prototype Cone)`, or
    `/World/Ring (prototype Cone, Body/Mesh)` for a prim inside the prototype."""
    rel = str(sub_path.MakeRelativePath(proto_path)) if sub_path.HasPrefix(proto_path) else str(sub_path)
    inside = "" if rel in (".", "") else f", {rel}"
    return f"{instancer} (prototype {proto_path.name}{inside})"


@dataclass
class GeomUnit:
    """One renderable prim (or one prototype mesh of a PointInstancer with all its instances)."""

    path: str
    prim: Usd.Prim
    local_tris: np.ndarray            # (T, 3) int32 indices into the unit's local points
    num_points: int
    points_at: Callable[[float], np.ndarray]          # time -> (N, 3) float64 local points
    transforms_at: Callable[[float, UsdGeom.XformCache], np.ndarray]  # -> (I, 4, 4) float64
    num_instances: int
    corner_colors: np.ndarray         # (T, 3, 3) float32 colour primvar (displayColor) at each triangle corner
    corner_uvs: np.ndarray | None     # (T, 3, 2) float32 texture coordinates at each corner, or None
    material: int
    flags: int
    blur_scale: float = 1.0
    visibility_prims: list = field(default_factory=list)
    tri_materials: np.ndarray | None = None   # (T,) int32 per local triangle (GeomSubset bindings), else `material`
    normals_at: Callable[[float], np.ndarray] | None = None   # time -> (N, 3) authored local normals (normals.py)
    corner_opacity: np.ndarray | None = None  # (T, 3) float32 opacity primvar (displayOpacity) at each corner

    visibility: tuple | None = None   # (may vary over time, the value when it does not): found on first use
    visibility_memo: dict | None = None   # the scene's (path -> visibility may vary) verdicts, shared

    def visible_at(self, time: float) -> bool:
        if self.visibility is None:   # once per prim: most never animate their visibility
            self.visibility = (visibility_varies(self.visibility_prims, self.visibility_memo),
                               prims_visible(self.visibility_prims, time))
        return prims_visible(self.visibility_prims, time) if self.visibility[0] else self.visibility[1]


def held_points(points: np.ndarray) -> Callable[[float], np.ndarray]:
    """A points function giving `points` (N, 3) at every time, marked held (see SmallUnitGroup)."""
    def points_at(time: float) -> np.ndarray:
        return points
    points_at.held = True
    return points_at


def prim_transform_fn(prim: Usd.Prim, memo: dict | None = None) -> Callable[[float, UsdGeom.XformCache], np.ndarray]:
    """transforms_at(time, XformCache of that time) -> (1, 4, 4) float64 local-to-world of the
    prim. Where neither its own ops nor an ancestor's may vary over time (most of a set's prims),
    the matrix read first is returned at every time, marked held: a snapshot of a stage with
    thousands of still prims otherwise asks USD for each of them (~7 µs a prim) again. memo: the
    transform_may_vary verdicts shared between a scene's prims."""
    if transform_may_vary(prim, memo):
        def transforms_at(time: float, cache: UsdGeom.XformCache) -> np.ndarray:
            return np.array(cache.GetLocalToWorldTransform(prim), np.float64)[None]
        transforms_at.prim = prim   # the prim's own transform: SmallUnitGroup may batch it (xform_ops.py)
        return transforms_at
    held: list[np.ndarray] = []

    def held_transform(time: float, cache: UsdGeom.XformCache) -> np.ndarray:
        if not held:
            held.append(np.array(cache.GetLocalToWorldTransform(prim), np.float64)[None])
        return held[0]
    held_transform.held = True
    return held_transform


def _held(fn) -> bool:
    """True when a unit's points_at / transforms_at gives one array at every time (its `held`)."""
    return bool(getattr(fn, "held", False))


@dataclass
class UnitRows:
    """The scene's units gathered into per-triangle rows (T triangles, V vertices), in unit order.
    Kept across frames with the units when every unit of a frame was kept (unit_cache.py): the
    arrays are read-only."""

    vertex_offsets: list[int]     # each unit's first row in the vertex array
    num_vertices: int
    tri_vertices: np.ndarray      # (T, 3) int32
    corner_colors: np.ndarray     # (3T, 3) float32, corner 3t + k of triangle t
    corner_uvs: np.ndarray        # (3T, 2) float32 (zeros where a unit has none)
    textured: bool                # some unit has texture coordinates
    tri_material: np.ndarray      # (T,) int32
    tri_flags: np.ndarray         # (T,) int32
    tri_unit: np.ndarray          # (T,) int32
    tri_object: np.ndarray        # (T,) int32 prim instance of each triangle
    corner_alpha: np.ndarray      # (T, 3) float32 opacity primvar at each corner, NaN where none is read
    closed_unit: np.ndarray       # (U,) bool: the unit's surface is closed (tessellate.is_closed_surface)

    @staticmethod
    def of(units: list[GeomUnit], frame: float) -> "UnitRows":
        """Gather `units` (closedness judged from their points at USD time `frame`)."""
        from .tessellate import is_closed_surface
        tris, colors, uvs, mats, flags, unit_of_tri, objects, alphas = [], [], [], [], [], [], [], []
        offsets = []
        v = 0
        num_objects = 0
        for ui, u in enumerate(units):
            offsets.append(v)
            for i in range(u.num_instances):
                tris.append(u.local_tris + v + i * u.num_points)
            n = len(u.local_tris) * u.num_instances
            colors.append(np.tile(u.corner_colors.reshape(-1, 3), (u.num_instances, 1)))
            unit_uvs = u.corner_uvs if u.corner_uvs is not None else np.zeros((len(u.local_tris), 3, 2), np.float32)
            uvs.append(np.tile(unit_uvs.reshape(-1, 2), (u.num_instances, 1)))
            mats.append(np.tile(u.tri_materials, u.num_instances).astype(np.int32) if u.tri_materials is not None
                        else np.full(n, u.material, np.int32))
            flags.append(np.full(n, u.flags, np.int32))
            alphas.append(np.tile(u.corner_opacity, (u.num_instances, 1)) if u.corner_opacity is not None
                          else np.full((n, 3), np.nan, np.float32))
            unit_of_tri.append(np.full(n, ui, np.int32))
            objects.append(np.repeat(np.arange(u.num_instances), len(u.local_tris)) + num_objects)
            num_objects += u.num_instances
            v += u.num_points * u.num_instances
        cat = lambda a, shape, dt: np.concatenate(a).astype(dt) if a else np.zeros(shape, dt)  # noqa: E731
        closed = np.array([is_closed_surface(u.local_tris, u.points_at(frame)) for u in units], bool)
        return UnitRows(offsets, v, cat(tris, (0, 3), np.int32), cat(colors, (0, 3), np.float32),
                        cat(uvs, (0, 2), np.float32), any(u.corner_uvs is not None for u in units),
                        cat(mats, (0,), np.int32), cat(flags, (0,), np.int32), cat(unit_of_tri, (0,), np.int32),
                        cat(objects, (0,), np.int32), cat(alphas, (0, 3), np.float32), closed)

    def freeze(self) -> "UnitRows":
        """Make the arrays read-only (rows kept across frames are shared by every frame's scene)."""
        for value in vars(self).values():
            if isinstance(value, np.ndarray):
                value.flags.writeable = False
        return self


#: prims with at most this many points (and one instance) are placed together
SMALL_UNIT_POINTS = 256
#: moving prims of a group whose xformOps are linear over the frame are placed by xform_ops.py
#: (False: every prim asks USD at every snapshot; bench/bench_props.py compares the two)
BATCH_XFORM_OPS = True
#: snapshots a frame places prim by prim before batching: reading the ops' values at the window's
#: breakpoints costs about what placing the prims two or three times does (3000 props: ~60 ms),
#: so a frame of one or two snapshots never batches; velocity's 12, analytic's 10 to 130 and
#: accumulation's 64 and more do
USD_PLACEMENTS_FIRST = 2


@dataclass
class SmallUnitGroup:
    """Single-instance units of one motion blur scale (one USD time each), placed together. A
    still group's units all hold their transform and points over the frame (a set's props): those
    are gathered at its first snapshot and kept, and its camera-space block is kept for as long as
    the camera holds still, so thousands of still prims cost a snapshot a few NumPy calls, or a
    copy, instead of thousands of Python calls (~8 ms a snapshot for 2000 quads)."""

    blur_scale: float
    units: list[int]              # indices into the scene's units
    rows: np.ndarray              # (V_group,) rows of their vertices in the scene's vertex array
    slot_of_vertex: np.ndarray    # (V_group,) each vertex's unit, as a position in `units`
    still: bool = False           # every unit's transforms_at and points_at is held
    held: tuple | None = None     # still groups: ((U, 4, 4) local-to-world, (V_group, 3) local points)
    held_visible: np.ndarray | None = None   # (U,) bool, once known that no unit's visibility may vary
    last_placed: tuple | None = None         # still groups: (camera matrix bytes, (V_group, 3) block)
    window: tuple | None = None   # (lo, hi) USD times the frame's snapshots ask of it (set by the scene)
    memo: dict | None = None      # the scene's transform_may_vary verdicts
    linear: tuple | None = None   # moving groups: (placed members, the others, LinearTransforms)
    moving_placements: int = 0    # snapshots this frame has asked of a moving group

    def place(self, units: list, t_prim: float, cache, cam_from_world: np.ndarray, positions: np.ndarray,
              unit_visible: np.ndarray) -> None:
        """Write the group's camera-space vertices at USD time t_prim into positions (V, 3) float64
        (cam_from_world: (4, 4) row-vector matrix; cache: the UsdGeom.XformCache of t_prim) and
        each unit's visibility into unit_visible: what Scene.snapshot does prim by prim."""
        key = cam_from_world.tobytes() if self.still else None
        if self.still and self.last_placed is not None and self.last_placed[0] == key:
            positions[self.rows] = self.last_placed[1]   # a still group seen from the same camera
        else:
            members = [units[ui] for ui in self.units]
            if self.still and self.held is None:
                self.held = (np.concatenate([u.transforms_at(t_prim, cache) for u in members]),
                             np.concatenate([u.points_at(t_prim) for u in members]))
            if self.held is not None:
                local, pts = self.held
            else:
                local = self._moving_transforms(members, t_prim, cache)
                pts = np.concatenate([u.points_at(t_prim) for u in members])
            mv = (local @ cam_from_world[None])[self.slot_of_vertex]                # (V_group, 4, 4)
            block = (pts[:, None, :] @ mv[:, :3, :3])[:, 0] + mv[:, 3, :3]
            positions[self.rows] = block
            if self.still:
                self.last_placed = (key, block)
        if self.held_visible is None:
            members = [units[ui] for ui in self.units]
            visible = np.array([u.visible_at(t_prim) for u in members], bool)
            if not any(u.visibility[0] for u in members):
                self.held_visible = visible
        else:
            visible = self.held_visible
        unit_visible[self.units] = visible


    def _moving_transforms(self, members: list, t_prim: float, cache) -> np.ndarray:
        """(U, 4, 4) local-to-world of the members at USD time t_prim: those whose xformOps are
        linear over the window from one batched pass (xform_ops.py), the others from USD."""
        self.moving_placements += 1
        if self.linear is None and self.window is not None and BATCH_XFORM_OPS \
                and self.moving_placements > USD_PLACEMENTS_FIRST:
            prims = [getattr(u.transforms_at, "prim", None) for u in members]
            rows = np.array([i for i, p in enumerate(prims) if p is not None], np.int64)
            batch = LinearTransforms([prims[i] for i in rows], *self.window, {} if self.memo is None else self.memo,
                                     cache, [members[i].transforms_at for i in rows])
            self.linear = (rows[batch.placed], np.setdiff1d(np.arange(len(members)), rows[batch.placed]), batch)
        if self.linear is None or not self.linear[2].covers(t_prim):
            return np.concatenate([u.transforms_at(t_prim, cache) for u in members])
        placed, rest, batch = self.linear
        out = np.empty((len(batch.placed), 4, 4))
        batch.at(t_prim, out)
        local = np.empty((len(members), 4, 4))
        local[placed] = out[batch.placed]
        for i in rest:
            local[i] = members[i].transforms_at(t_prim, cache)[0]
        return local


def small_unit_groups(units: list, vertex_offsets: list[int], frame: float | None = None,
                      shutter: tuple[float, float] | None = None, memo: dict | None = None) -> list[SmallUnitGroup]:
    """Groups of at least two single-instance units of at most SMALL_UNIT_POINTS points each, one
    group per motion blur scale and stillness (held transform and points); the other units are
    placed one by one. frame, shutter (open, close USD times) give each group the window of USD
    times its snapshots ask for (t_prim: the shutter scaled about the frame by its blur scale);
    memo: the scene's transform_may_vary verdicts."""
    by_key: dict[tuple[float, bool], list[int]] = {}
    for ui, u in enumerate(units):
        if u.num_instances == 1 and u.num_points <= SMALL_UNIT_POINTS:
            still = _held(u.transforms_at) and _held(u.points_at)
            by_key.setdefault((u.blur_scale, still), []).append(ui)
    groups = []
    for (scale, still), members in by_key.items():
        if len(members) < 2:
            continue
        counts = np.array([units[ui].num_points for ui in members])
        rows = np.concatenate([np.arange(vertex_offsets[ui], vertex_offsets[ui] + units[ui].num_points)
                               for ui in members])
        group = SmallUnitGroup(scale, members, rows, np.repeat(np.arange(len(members)), counts), still)
        if frame is not None and shutter is not None:
            ends = sorted(frame + (t - frame) * scale for t in shutter)
            group.window, group.memo = (ends[0], ends[1]), memo
        groups.append(group)
    return groups
