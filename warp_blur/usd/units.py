"""A scene's renderable units (GeomUnit: a prim, or a PointInstancer prototype's mesh with all
its instances), and the groups of small ones that snapshots place in camera space together: the
per-prim NumPy calls cost more than their arithmetic where a stage has dozens of quads
(deep_overlap: 48 prims, 1.5 ms a snapshot, ~0.7 ms of it per-prim overhead; a frame's motion plan
takes 34 to 129 snapshots)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np
from pxr import Usd, UsdGeom

from .stage import prims_visible, visibility_varies

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

    def visible_at(self, time: float) -> bool:
        if self.visibility is None:   # once per prim: most never animate their visibility
            self.visibility = (visibility_varies(self.visibility_prims), prims_visible(self.visibility_prims, time))
        return prims_visible(self.visibility_prims, time) if self.visibility[0] else self.visibility[1]


#: prims with at most this many points (and one instance) are placed together
SMALL_UNIT_POINTS = 256


@dataclass
class SmallUnitGroup:
    """Single-instance units of one motion blur scale (one USD time each), placed together."""

    blur_scale: float
    units: list[int]              # indices into the scene's units
    rows: np.ndarray              # (V_group,) rows of their vertices in the scene's vertex array
    slot_of_vertex: np.ndarray    # (V_group,) each vertex's unit, as a position in `units`

    def place(self, units: list, t_prim: float, cache, cam_from_world: np.ndarray, positions: np.ndarray,
              unit_visible: np.ndarray) -> None:
        """Write the group's camera-space vertices at USD time t_prim into positions (V, 3) float64
        (cam_from_world: (4, 4) row-vector matrix; cache: the UsdGeom.XformCache of t_prim) and
        each unit's visibility into unit_visible: what Scene.snapshot does prim by prim."""
        m = np.concatenate([units[ui].transforms_at(t_prim, cache) for ui in self.units]) @ cam_from_world[None]
        pts = np.concatenate([units[ui].points_at(t_prim) for ui in self.units])
        mv = m[self.slot_of_vertex]                                             # (V_group, 4, 4)
        positions[self.rows] = (pts[:, None, :] @ mv[:, :3, :3])[:, 0] + mv[:, 3, :3]
        for ui in self.units:
            unit_visible[ui] = units[ui].visible_at(t_prim)


def small_unit_groups(units: list, vertex_offsets: list[int]) -> list[SmallUnitGroup]:
    """Groups of at least two single-instance units of at most SMALL_UNIT_POINTS points each, one
    group per motion blur scale; the other units are placed one by one."""
    by_scale: dict[float, list[int]] = {}
    for ui, u in enumerate(units):
        if u.num_instances == 1 and u.num_points <= SMALL_UNIT_POINTS:
            by_scale.setdefault(u.blur_scale, []).append(ui)
    groups = []
    for scale, members in by_scale.items():
        if len(members) < 2:
            continue
        counts = np.array([units[ui].num_points for ui in members])
        rows = np.concatenate([np.arange(vertex_offsets[ui], vertex_offsets[ui] + units[ui].num_points)
                               for ui in members])
        groups.append(SmallUnitGroup(scale, members, rows, np.repeat(np.arange(len(members)), counts)))
    return groups
