"""UsdSkel linear blend skinning through USD's own queries: which meshes a skeleton skins, and
their points at a time (in skeleton space, as UsdSkel defines them)."""

from __future__ import annotations

from typing import Callable

import numpy as np
from pxr import Usd, UsdGeom, UsdSkel

from ..core.errors import InvalidGeometryError


class Skins:
    """The stage's UsdSkel.Cache, populated per skeleton root on first use."""

    def __init__(self) -> None:
        self._cache: UsdSkel.Cache | None = None
        self._roots: set = set()

    def find(self, prim: Usd.Prim):
        """(skinning query, skel query, skeleton prim) when UsdSkel skins this mesh, else None."""
        if not prim.HasAPI(UsdSkel.BindingAPI):
            return None
        skel = UsdSkel.BindingAPI(prim).GetInheritedSkeleton()
        root = UsdSkel.Root.Find(prim)
        if not skel or not root:
            return None
        if self._cache is None:
            self._cache = UsdSkel.Cache()
        if root.GetPath() not in self._roots:
            self._cache.Populate(root, Usd.TraverseInstanceProxies(Usd.PrimDefaultPredicate))
            self._roots.add(root.GetPath())
        skinning = self._cache.GetSkinningQuery(prim)
        skel_query = self._cache.GetSkelQuery(skel)
        if not skinning or not skinning.HasJointInfluences() or not skel_query:
            return None
        return skinning, skel_query, skel.GetPrim()


def skinned_points_fn(prim: Usd.Prim, npts: int, skin) -> Callable[[float], np.ndarray]:
    """time -> (npts, 3) float64 points as USD's linear blend skinning computes them (skeleton
    space); skin is Skins.find's triple."""
    skinning, skel_query, _ = skin
    attr = UsdGeom.Mesh(prim).GetPointsAttr()
    path = str(prim.GetPath())

    def points_at(time: float) -> np.ndarray:
        t = Usd.TimeCode(time)
        pts = attr.Get(t)
        xforms = skel_query.ComputeSkinningTransforms(t)
        if pts is None or xforms is None or not skinning.ComputeSkinnedPoints(xforms, pts, t):
            raise InvalidGeometryError(path, f"UsdSkel could not skin the points at time {time}")
        arr = np.asarray(pts, np.float64).reshape(-1, 3)
        if len(arr) != npts or not np.isfinite(arr).all():
            raise InvalidGeometryError(path, f"skinned points are invalid at time {time}")
        return arr

    return points_at
