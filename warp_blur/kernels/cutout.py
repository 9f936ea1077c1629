"""Cutout opacity (UsdPreviewSurface `opacity` with `opacityThreshold` > 0) as a hit test shared
by every method and the shadow maps: a surface point whose opacity is below the threshold is
not there (rays pass through it); every other point is opaque, as USD's masked materials are.

Each triangle's test is geo.tri_cutout[t] = (code, threshold): code -1 no test, -2 hidden
everywhere (a constant opacity below the threshold), else the texture binding of `opacity`,
looked up at the point's texture coordinates with the triangle's level of detail.
"""

from __future__ import annotations

import warp as wp

from .kernel_types import Geometry
from .texture_lookup import binding_value


@wp.func
def cutout_hides(geo: Geometry, tri: int, wb: float, wc: float) -> bool:
    """True when triangle tri's point at barycentrics (1 - wb - wc, wb, wc) is cut out."""
    if geo.has_cutouts == 0:
        return False
    c = geo.tri_cutout[tri]
    code = int(c[0])
    if code == -1:
        return False
    if code == -2:
        return True
    uv = wp.vec2(0.0, 0.0)
    lod = float(-30.0)
    if geo.tri_uvs.shape[0] >= 3 * tri + 3:
        uv = (1.0 - wb - wc) * geo.tri_uvs[3 * tri] + wb * geo.tri_uvs[3 * tri + 1] + wc * geo.tri_uvs[3 * tri + 2]
        lod = geo.tri_lod[tri]
    return binding_value(geo.tex, code, uv, lod)[0] < c[1]


@wp.func
def has_cutout(geo: Geometry, tri: int) -> bool:
    """True when triangle tri has a cutout test (its coverage then depends on where it is hit)."""
    if geo.has_cutouts == 0:
        return False
    return int(geo.tri_cutout[tri][0]) != -1
