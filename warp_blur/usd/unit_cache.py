"""A Renderer's geometry units kept from frame to frame where nothing they were read from can change.

Reading a mesh prim or implicit gprim into a GeomUnit (topology and its triangulation, primvars,
material binding, GeomSubsets, authored normals) costs ~0.35 ms: a set of 2000 props took 0.7 s a
frame to read again. A unit is a function of time only through its points, transform and
visibility functions, which read USD at the time asked. So a unit read at one frame is the unit of
every frame when:
- no attribute of the prim other than its xformOps and visibility may take different values at
  different times (time samples, value clips, splines): its points then hold still too, and the
  points function has no per-frame fallback to take;
- nor may an attribute of its GeomSubsets, nor an ancestor's motion:blurScale (it is inherited);
- it has no velocities (points are extrapolated from the frame) and no skeleton binding; a
  subdivision mesh is kept with the Catmull-Clark level it was read at, which follows its size on
  screen: a frame that needs another level reads it again;
- its material table is the one the Renderer keeps across frames (material_cache.py), whose rows
  its indices point at: on a stage whose shading may change over time every frame has a table
  of its own, and no unit is kept there.
Other prims are read every frame, as before. An edit to the stage (the caller's to make between
frames) drops every kept unit and verdict (an edit may animate what was still), except edits
under the `ignored` prim path (the framing camera the renderer places each frame). One Renderer
renders one frame at a time.
"""

from __future__ import annotations

from pxr import Sdf, Tf, Usd, UsdGeom

from .units import GeomUnit, UnitRows

#: attributes a unit reads by time (its points function is the points' reader only for still
#: points: an animated `points` makes the prim unkeepable below)
_READ_BY_TIME = ("visibility", "xformOpOrder")
_BLUR_SCALE = "motion:blurScale"


def _varies(attr: Usd.Attribute) -> bool:
    return attr.ValueMightBeTimeVarying()


def keepable(prim: Usd.Prim) -> bool:
    """True when a unit read from `prim` at one frame is its unit at every frame (module docstring;
    the skeleton binding is the Scene's to tell, the material table's identity UnitCache's)."""
    if prim.IsA(UsdGeom.PointBased) and UsdGeom.PointBased(prim).GetVelocitiesAttr().HasAuthoredValue():
        return False
    for attr in prim.GetAttributes():
        name = attr.GetName()
        if name in _READ_BY_TIME or name.startswith("xformOp:"):
            continue
        if _varies(attr):
            return False
    for child in prim.GetChildren():
        if child.IsA(UsdGeom.Subset) and any(_varies(a) for a in child.GetAttributes()):
            return False
    p = prim.GetParent()
    while p and not p.IsPseudoRoot():
        attr = p.GetAttribute(_BLUR_SCALE)
        if attr and _varies(attr):
            return False
        p = p.GetParent()
    return True


class UnitCache:
    """Units kept for prims that keepable() passes, by prim path, with the material table they
    were read against; verdicts are kept for the other prims too, so each prim is judged once
    between edits."""

    def __init__(self, stage: Usd.Stage, ignored: str | None = None) -> None:
        self._ignored = Sdf.Path(ignored) if ignored else None
        self._units: dict[Sdf.Path, tuple[GeomUnit, object, int | None]] = {}   # (unit, table, level)
        self._verdicts: dict[Sdf.Path, bool] = {}
        self._rows: tuple[tuple[GeomUnit, ...], UnitRows] | None = None   # (units, their rows)
        self.reused = 0        # units given again since the Renderer was made (tests read it)
        self.rows_reused = 0   # frames given kept rows (tests read it)
        # Tf holds a bound method's instance weakly: no cycle keeps a dropped Renderer's units alive
        self._listener = Tf.Notice.Register(Usd.Notice.ObjectsChanged, self._changed, stage)

    def _changed(self, notice, _sender) -> None:
        paths = list(notice.GetResyncedPaths()) + list(notice.GetChangedInfoOnlyPaths())
        if paths and self._ignored is not None and all(path.HasPrefix(self._ignored) for path in paths):
            return
        self._units.clear()
        self._verdicts.clear()
        self._rows = None

    def get(self, prim: Usd.Prim, table, level: int | None = None) -> GeomUnit | None:
        """The unit kept for `prim` when it was read against `table` (the frame's material table)
        at subdivision level `level` (None: a polygon mesh or gprim)."""
        kept = self._units.get(prim.GetPath())
        if kept is None or kept[1] is not table or kept[2] != level:
            return None
        self.reused += 1
        return kept[0]

    def keep(self, prim: Usd.Prim, unit: GeomUnit, table, level: int | None = None) -> None:
        """Keep `unit`, just read from `prim` against `table` at subdivision level `level`, if the
        prim is keepable (the Scene offers no skinned mesh: its points follow the skeleton)."""
        path = prim.GetPath()
        verdict = self._verdicts.get(path)
        if verdict is None:
            verdict = self._verdicts[path] = keepable(prim)
        if verdict:
            self._units[path] = (unit, table, level)

    def rows_for(self, units: list[GeomUnit]) -> UnitRows | None:
        """The rows kept for exactly these units, the same objects in this order (keep_rows), else None."""
        if self._rows is None or len(self._rows[0]) != len(units):
            return None
        if not all(a is b for a, b in zip(self._rows[0], units)):
            return None
        self.rows_reused += 1
        return self._rows[1]

    def keep_rows(self, units: list[GeomUnit], rows: UnitRows) -> None:
        """Keep the rows gathered from `units`, every one of them a kept unit (held by reference:
        the key is the units themselves)."""
        self._rows = (tuple(units), rows.freeze())
