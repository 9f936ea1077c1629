"""Opacity as a hit test shared by every method and the shadow maps.

Cutouts (UsdPreviewSurface `opacity` with `opacityThreshold` > 0): a surface point whose opacity
is below the threshold is not there (rays pass through it); every other point is opaque, as
USD's masked materials are.

Fractional opacity (threshold 0, opacity α < 1): the point is there at a fraction α of a
sample position's time samples (stratified stochastic transparency): present when α exceeds
ξ = frac(h + k·step), k the time slot of the sample (PRESENCE_SLOTS per shutter), h a hash of
the triangle and the sample position, step an irrational number picked by the triangle (so
that two layers' sequences are independent). Averaged over a method's time samples, a surface
covers α of them, and layers composite as α1 + (1 − α1) α2 on average: order-independent
transparency, unbiased, noisy only where few samples are taken (the velocity method's one
instant dithers).

Each triangle's test is geo.tri_cutout[t] = (code, threshold, opacity): code -1 no test, -2
hidden everywhere (a constant opacity below the threshold), -3 constant opacity (fractional),
-4 the corners' opacity primvar (displayOpacity; geo.tri_alpha[t]) interpolated at the point,
else the texture binding of `opacity`, looked up at the point's texture coordinates with the
triangle's level of detail; threshold > 0 masks, else the opacity is fractional.
"""

from __future__ import annotations

import warp as wp

from .kernel_types import Geometry
from .texture_lookup import binding_value

PRESENCE_SLOTS = wp.constant(4096)


#: Eight irrational steps (the golden ratio's and square roots' fractional parts), one per
#: triangle (tri % 8), so that overlapping layers' presence sequences are independent.
_vec8 = wp.types.vector(length=8, dtype=wp.float32)
PRESENCE_STEPS = wp.constant(_vec8(0.6180339887, 0.4142135624, 0.7320508076, 0.2360679775, 0.6457513111,
                                   0.3166247904, 0.6055512755, 0.1231056256))


@wp.func
def presence_threshold(tri: int, sx: float, sy: float, u: float, shift: int) -> float:
    """ξ in [0, 1) of triangle tri at sample position (sx, sy) (pixels) and shutter time u, its
    time slot moved on by `shift` (geo.presence_shift: the velocity method's presence passes)."""
    ix = int(wp.floor(sx * 16.0))
    iy = int(wp.floor(sy * 16.0))
    state = wp.rand_init(tri, ix + iy * 8191)
    h = wp.randf(state)
    k = wp.clamp(int(u * float(PRESENCE_SLOTS)), 0, PRESENCE_SLOTS - 1) + shift
    x = h + PRESENCE_STEPS[tri % 8] * float(k)
    return x - wp.floor(x)


@wp.func
def cutout_opacity(geo: Geometry, tri: int, wb: float, wc: float) -> float:
    """Opacity of triangle tri (which has a test: code not -1) at barycentrics (1 - wb - wc, wb,
    wc): its constant, its corners' primvar or its texture there; -1 where it is hidden everywhere
    (code -2), which opacity_hides then always hides."""
    c = geo.tri_cutout[tri]
    code = int(c[0])
    if code == -2:
        return -1.0
    opacity = c[2]
    if code == -4:
        a = geo.tri_alpha[tri]
        opacity = (1.0 - wb - wc) * a[0] + wb * a[1] + wc * a[2]
    if code >= 0:
        uv = wp.vec2(0.0, 0.0)
        lod = float(-30.0)
        if geo.tri_uvs.shape[0] >= 3 * tri + 3:
            uv = (1.0 - wb - wc) * geo.tri_uvs[3 * tri] + wb * geo.tri_uvs[3 * tri + 1] + wc * geo.tri_uvs[3 * tri + 2]
            lod = geo.tri_lod[tri]
        opacity = binding_value(geo.tex, code, uv, lod)[0]
    return opacity


@wp.func
def opacity_hides(geo: Geometry, tri: int, opacity: float, u: float, sx: float, sy: float) -> bool:
    """True when a point of triangle tri (which has a test) with this opacity is not there for the
    sample at (sx, sy) and shutter time u: below a cutout's threshold, or absent at u's slot."""
    threshold = geo.tri_cutout[tri][1]
    if threshold > 0.0:
        return opacity < threshold
    return opacity <= presence_threshold(tri, sx, sy, u, geo.presence_shift)


@wp.func
def cutout_hides(geo: Geometry, tri: int, wb: float, wc: float, u: float, sx: float, sy: float) -> bool:
    """True when triangle tri's point at barycentrics (1 - wb - wc, wb, wc) is not there for the
    sample at position (sx, sy) (pixels) and shutter time u."""
    if geo.has_cutouts == 0:
        return False
    code = int(geo.tri_cutout[tri][0])
    if code == -1:
        return False
    if code == -2:
        return True
    return opacity_hides(geo, tri, cutout_opacity(geo, tri, wb, wc), u, sx, sy)


@wp.func
def has_cutout(geo: Geometry, tri: int) -> bool:
    """True when triangle tri has an opacity test (its coverage then depends on where it is hit)."""
    if geo.has_cutouts == 0:
        return False
    return int(geo.tri_cutout[tri][0]) != -1


@wp.func
def is_fractional(geo: Geometry, tri: int) -> bool:
    """True when triangle tri's opacity is fractional (its presence changes with time slots)."""
    if geo.has_cutouts == 0:
        return False
    c = geo.tri_cutout[tri]
    return int(c[0]) != -1 and int(c[0]) != -2 and c[1] <= 0.0
