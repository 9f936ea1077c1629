"""Primvars at triangle corners: every interpolation USD allows, flattened (indexed primvars
resolved by USD), as (T, 3, width) float32 arrays that the kernels interpolate barycentrically."""

from __future__ import annotations

import numpy as np
from pxr import Usd, UsdGeom

from ..core.log import warn_once
from .values import unregistered


def corner_primvar(prim: Usd.Prim, name: str, time: Usd.TimeCode, tris: np.ndarray, face_of_tri: np.ndarray,
                   corners: np.ndarray | None, width: int) -> np.ndarray | None:
    """(T, 3, width) float32 values of primvar `name` at each triangle corner, or None when the
    prim has no such primvar, or (warned) when its values do not fit the topology or are not finite.

    tris: (T, 3) point indices; face_of_tri: (T,) face of each triangle; corners: (T, 3)
    face-vertex positions (None: faceVarying values cannot be placed)."""
    pv = UsdGeom.PrimvarsAPI(prim).GetPrimvar(name)
    if not pv or not pv.HasValue():
        return None
    path = prim.GetPath()
    try:
        raw = pv.ComputeFlattened(time)
        vals = None if raw is None else np.asarray(raw, np.float32).reshape(-1, width)
    except (TypeError, ValueError):
        vals = None
        what = ("is authored with a type USD does not know" if unregistered(pv.GetAttr().Get(time))
                else f"does not hold {width} numbers a value")
        warn_once(f"primvar-type:{path}:{name}", f"{path}: primvar {name} {what}; ignored")
    if vals is None or len(vals) == 0:
        return None
    if not np.isfinite(vals).all():
        warn_once(f"primvar-nan:{path}:{name}", f"{path}: primvar {name} has non-finite values; ignored")
        return None
    interp = pv.GetInterpolation()
    n = len(tris)
    try:
        if interp == UsdGeom.Tokens.constant or len(vals) == 1:
            return np.broadcast_to(vals[0], (n, 3, width)).copy()
        if interp == UsdGeom.Tokens.uniform:
            return np.repeat(vals[face_of_tri][:, None], 3, axis=1)
        if interp in (UsdGeom.Tokens.vertex, UsdGeom.Tokens.varying):
            return vals[tris]
        if interp == UsdGeom.Tokens.faceVarying and corners is not None:
            return vals[corners]
    except IndexError:
        pass
    warn_once(f"primvar-fit:{path}:{name}", f"{path}: primvar {name} ({interp}, {len(vals)} values) does not "
                                             f"match the topology; ignored")
    return None


def grey_corners(n: int) -> np.ndarray:
    """(n, 3, 3) float32 mid grey, UsdImaging's displayColor when none is authored."""
    return np.full((n, 3, 3), 0.5, np.float32)
