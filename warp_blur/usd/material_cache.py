"""A Renderer's material table, kept from frame to frame while nothing it was read from can change.

Reading a UsdPreviewSurface network costs ~0.3 ms a material (UsdShade connection lookups, input
values, texture bindings): a third to a half of a frame's scene load on stages with many
materials. A table read at one frame is the table of every frame when no attribute of any shading
prim (Material, NodeGraph, Shader) or of a prim their inputs connect to is time-varying, so such a
stage's table is read once and reused (read again when an image file it read has been rewritten
since); any other stage gets a fresh table each frame, as before. The table's TextureSet also
holds the dome's map and radiance, so an animated dome input counts as well.
An edit to the stage (a Renderer's stage is the caller's to change between frames) drops the
kept table and the verdict, except edits under the `ignored` prim path (the framing camera that
the renderer itself places each frame). One Renderer renders one frame at a time.
"""

from __future__ import annotations

from pxr import Sdf, Tf, Usd, UsdLux, UsdShade

from .materials import MaterialTable

_SHADING_TYPES = (UsdShade.Material, UsdShade.NodeGraph, UsdShade.Shader)
#: their texture and radiance go into the table's TextureSet too (dome.dome_map): their inputs count
_DOME_TYPES = (UsdLux.DomeLight, UsdLux.DomeLight_1)


def shading_is_static(stage: Usd.Stage) -> bool:
    """True when no attribute of a shading prim, or of a prim one of their attributes connects
    to, may take different values at different times (time samples, value clips, splines), nor
    any input of a dome light (its map and radiance are kept in the table's TextureSet)."""
    checked: set[Sdf.Path] = set()
    pending: list[Usd.Prim] = []
    for prim in Usd.PrimRange.Stage(stage, Usd.TraverseInstanceProxies()):
        if any(prim.IsA(kind) for kind in _SHADING_TYPES):
            pending.append(prim)
        elif any(prim.IsA(kind) for kind in _DOME_TYPES):
            if any(a.GetName().startswith("inputs:") and a.ValueMightBeTimeVarying() for a in prim.GetAttributes()):
                return False
    while pending:
        prim = pending.pop()
        if prim.GetPath() in checked:
            continue
        checked.add(prim.GetPath())
        for attr in prim.GetAttributes():
            if attr.ValueMightBeTimeVarying():
                return False
            for source in attr.GetConnections():
                other = stage.GetPrimAtPath(source.GetPrimPath())
                if other and other.GetPath() not in checked:
                    pending.append(other)
    return True


class MaterialCache:
    """The material table to build a frame's Scene with (table_for): one kept for every frame
    while the stage's shading is static, else a new one a frame."""

    def __init__(self, stage: Usd.Stage, ignored: str | None = None) -> None:
        self._stage = stage
        self._ignored = Sdf.Path(ignored) if ignored else None
        self._table: MaterialTable | None = None
        self._static: bool | None = None   # None: not decided since the last edit
        self.reused = 0                      # frames given a kept table (tests read it)
        # Tf holds a bound method's instance weakly: no cycle keeps a dropped Renderer's textures alive
        self._listener = Tf.Notice.Register(Usd.Notice.ObjectsChanged, self._changed, stage)

    def _changed(self, notice, _sender) -> None:
        paths = list(notice.GetResyncedPaths()) + list(notice.GetChangedInfoOnlyPaths())
        if paths and self._ignored is not None and all(path.HasPrefix(self._ignored) for path in paths):
            return
        self._table = None
        self._static = None

    def table_for(self, frame: float) -> MaterialTable:
        """A table to read frame `frame`'s materials into (it may hold rows already)."""
        if self._static is None:
            self._static = shading_is_static(self._stage)
        if not self._static:
            return MaterialTable(frame)
        if self._table is None or self._table.textures.files_changed():
            self._table = MaterialTable(frame)
        else:
            self.reused += 1
        return self._table
