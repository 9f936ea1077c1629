"""The dome as the kernels see it: its radiance along a camera-space ray (background) and the
irradiance it gives a normal (diffuse ambient), textured or uniform (usd/dome.py's layout)."""

from __future__ import annotations

import warp as wp

from .kernel_types import Shading
from .texture_lookup import binding_value

PI = wp.constant(3.14159265358979)

#: at most this many lookups average a textured dome over a span of shutter time when the
#: camera turns (midpoints of equal parts; a whole-shutter span takes them all)
DOME_TIME_STEPS = wp.constant(32)


@wp.func
def dome_lookup(sh: Shading, rot: wp.mat33, d: wp.vec3) -> wp.vec3:
    """Textured dome radiance along camera-space direction d under camera-to-dome rotation rot."""
    v = wp.normalize(rot * d)
    lat = wp.asin(wp.clamp(v[1], -1.0, 1.0))
    lon = wp.atan2(v[0], v[2])
    uv = wp.vec2(0.5 - lon / (2.0 * PI), 0.5 + lat / PI)
    return binding_value(sh.tex, sh.dome_binding, uv, sh.dome_lod)


@wp.func
def dome_along(sh: Shading, d: wp.vec3) -> wp.vec3:
    """Dome radiance seen along camera-space direction d (any length), at the shutter centre."""
    if sh.dome_binding < 0:
        return sh.dome
    return dome_lookup(sh, sh.dome_rot, d)


@wp.func
def dome_rot_at(sh: Shading, u: float) -> wp.mat33:
    """The camera-to-dome rotation at shutter time u (linear between knots; dome_lookup
    normalises the direction it gives)."""
    if sh.dome_segments == 0:
        return sh.dome_rot
    x = wp.clamp(u, 0.0, 1.0) * float(sh.dome_segments)
    k = wp.min(int(x), sh.dome_segments - 1)
    f = x - float(k)
    return sh.dome_rots[k] * (1.0 - f) + sh.dome_rots[k + 1] * f


@wp.func
def dome_at(sh: Shading, d: wp.vec3, u: float) -> wp.vec3:
    """Dome radiance along camera-space direction d at shutter time u (a turning camera sweeps it)."""
    if sh.dome_binding < 0:
        return sh.dome
    if sh.dome_segments == 0:
        return dome_lookup(sh, sh.dome_rot, d)
    return dome_lookup(sh, dome_rot_at(sh, u), d)


@wp.func
def dome_over(sh: Shading, d: wp.vec3, a: float, b: float) -> wp.vec3:
    """Mean dome radiance along camera-space direction d over shutter times [a, b]."""
    if sh.dome_binding < 0:
        return sh.dome
    if sh.dome_segments == 0:
        return dome_lookup(sh, sh.dome_rot, d)
    n = wp.clamp(int(wp.ceil((b - a) * float(DOME_TIME_STEPS))), 1, DOME_TIME_STEPS)
    acc = wp.vec3(0.0, 0.0, 0.0)
    for i in range(n):
        acc = acc + dome_lookup(sh, dome_rot_at(sh, a + (b - a) * (float(i) + 0.5) / float(n)), d)
    return acc / float(n)


@wp.func
def dome_ambient(sh: Shading, n: wp.vec3) -> wp.vec3:
    """E(n) / pi of the dome at camera-space unit normal n (a uniform dome: its radiance)."""
    if sh.dome_binding < 0:
        return sh.dome
    v = sh.dome_rot * n
    x = v[0]
    y = v[1]
    z = v[2]
    e = sh.dome_sh[0] * 0.282095
    e = e + sh.dome_sh[1] * (0.488603 * y) + sh.dome_sh[2] * (0.488603 * z) + sh.dome_sh[3] * (0.488603 * x)
    e = e + sh.dome_sh[4] * (1.092548 * x * y) + sh.dome_sh[5] * (1.092548 * y * z)
    e = e + sh.dome_sh[6] * (0.315392 * (3.0 * z * z - 1.0)) + sh.dome_sh[7] * (1.092548 * x * z)
    e = e + sh.dome_sh[8] * (0.546274 * (x * x - y * y))
    return wp.vec3(wp.max(e[0], 0.0), wp.max(e[1], 0.0), wp.max(e[2], 0.0)) / PI
