"""Radiance of a stored interval, computed only where the resolve finds it visible (hidden
intervals are never shaded).

An interval [s_a, s_b] (entry times) of entry e is shaded
- linearly (a reflecting surface, more than one shading sample): radiance at both ends and in the
  middle; a middle off the ends' mean by c splits the interval into n >= sqrt(4 c × 256) equal
  sub-pieces (capped at `samples`), each linear in time between its ends, which keeps a smoothly
  curving radiance (off linear by c / n² per sub-piece) within 1/1024 of each sub-piece's line.
  An end where the interval meets an adjacent motion segment's interval of the same triangle
  (the same point at the same time) takes the radiance that interval was shaded with there
  (radiance_plan_known; the bitmask resolve keeps its last two linear intervals for this);
- or as one constant (emissive-only material, a static surface under static lights, or one
  shading sample): the radiance in its middle, shadows averaged over its shutter span (a static
  receiver seen for all of it sees a moving shadow's whole time average; the resolve averages a
  partly hidden one over the times it is seen, and shades a short interval once).
"""

from __future__ import annotations

import warp as wp

from ...kernels.kernel_types import Geometry, Shading, View
from ...kernels.shading import max_component, shade_corners_span
from .moving import Moving, plane_hit

SHADE_TOLERANCE = wp.constant(1.0 / 256.0)


# inlined: out of line, every shading would copy View, Geometry and Shading (~2 KB) by value
@wp.func(inline=True)
def radiance_at(view: View, geo: Geometry, sh: Shading, e: int, m: Moving, o: wp.vec3, d: wp.vec3, s: float,
                span: float) -> wp.vec3:
    """Radiance of entry e (its triangle m) seen along the ray at entry time s, with shadows
    averaged over `span` (shutter fraction) around it (0: at that instant)."""
    da = m.a1 - m.a0
    db = m.b1 - m.b0
    dc = m.c1 - m.c0
    a = m.a0 + s * da
    b = m.b0 + s * db
    c = m.c0 + s * dc
    return shade_corners_span(view, geo, sh, e, s, a, b, c, da, db, dc, m.u0 + s * (m.u1 - m.u0), span, o, d,
                              plane_hit(o, d, a, b, c))


@wp.func
def shade_at(view: View, geo: Geometry, sh: Shading, e: int, m: Moving, o: wp.vec3, d: wp.vec3, s: float) -> wp.vec3:
    """Radiance of entry e (its triangle m) seen along the ray at entry time s."""
    return radiance_at(view, geo, sh, e, m, o, d, s, 0.0)


@wp.func
def span_radiance(view: View, geo: Geometry, sh: Shading, e: int, m: Moving, o: wp.vec3, d: wp.vec3,
                  s0: float, s1: float) -> wp.vec3:
    """Radiance of [s0, s1] at its middle, with shadows averaged over its shutter span."""
    return radiance_at(view, geo, sh, e, m, o, d, 0.5 * (s0 + s1), (s1 - s0) * (m.u1 - m.u0))


@wp.func
def entry_emissive_only(geo: Geometry, sh: Shading, e: int) -> int:
    """1 when entry e's material reflects nothing (its radiance is its constant emission)."""
    mat = geo.tri_material[geo.entry_tri[e]]
    if sh.materials[mat, 10] < 0.5 and sh.materials[mat, 21] < 0.5:
        if wp.length_sq(wp.vec3(sh.materials[mat, 0], sh.materials[mat, 1], sh.materials[mat, 2])) == 0.0:
            if wp.length_sq(wp.vec3(sh.materials[mat, 6], sh.materials[mat, 7], sh.materials[mat, 8])) == 0.0:
                return 1
    return 0


@wp.func
def static_receiver(geo: Geometry, sh: Shading, e: int, lights_static: int) -> int:
    """1 when entry e is a still, reflecting surface under lights that hold still (its radiance
    changes over the shutter only where shadows move)."""
    if lights_static != 0 and geo.entry_k0[e] == geo.entry_k1[e]:
        return 1 - entry_emissive_only(geo, sh, e)
    return 0


@wp.func
def constant_radiance(geo: Geometry, sh: Shading, e: int, n_shade_max: int, lights_static: int) -> int:
    """1 when entry e's intervals are shaded as one constant each (see the module docstring)."""
    if n_shade_max <= 1:
        return 1
    if lights_static != 0 and geo.entry_k0[e] == geo.entry_k1[e]:
        return 1
    return entry_emissive_only(geo, sh, e)


@wp.func
def radiance_plan(view: View, geo: Geometry, sh: Shading, e: int, m: Moving, o: wp.vec3, d: wp.vec3,
                  s_a: float, s_b: float, n_shade_max: int, lights_static: int):
    """How [s_a, s_b] is shaded: (sub-pieces n, linear, radiance at s_a, at the middle, at s_b);
    a constant interval has n = 1, linear = 0 and its radiance in all three."""
    return radiance_plan_known(view, geo, sh, e, m, o, d, s_a, s_b, n_shade_max, lights_static, 0,
                               wp.vec3(0.0, 0.0, 0.0), wp.vec3(0.0, 0.0, 0.0))


@wp.func
def radiance_plan_known(view: View, geo: Geometry, sh: Shading, e: int, m: Moving, o: wp.vec3, d: wp.vec3,
                        s_a: float, s_b: float, n_shade_max: int, lights_static: int, known: int,
                        known_a: wp.vec3, known_b: wp.vec3):
    """radiance_plan, with the radiance at s_a (known bit 1) and at s_b (bit 2) of a linear
    interval taken as given (an adjacent motion segment's interval shaded there: junctions)."""
    n = int(1)
    linear = int(0)
    la = wp.vec3(0.0, 0.0, 0.0)
    lm = wp.vec3(0.0, 0.0, 0.0)
    lb = wp.vec3(0.0, 0.0, 0.0)
    if constant_radiance(geo, sh, e, n_shade_max, lights_static) != 0:
        la = span_radiance(view, geo, sh, e, m, o, d, s_a, s_b)
        lm = la
        lb = la
    else:
        linear = 1
        if (known & 1) != 0:
            la = known_a
        else:
            la = shade_at(view, geo, sh, e, m, o, d, s_a)
        lm = shade_at(view, geo, sh, e, m, o, d, 0.5 * (s_a + s_b))
        if (known & 2) != 0:
            lb = known_b
        else:
            lb = shade_at(view, geo, sh, e, m, o, d, s_b)
        dev = max_component(wp.abs(lm - 0.5 * (la + lb))) * 4.0
        n = wp.clamp(int(wp.ceil(wp.sqrt(dev / SHADE_TOLERANCE))), 1, n_shade_max)
    return n, linear, la, lm, lb


@wp.func
def boundary_radiance(view: View, geo: Geometry, sh: Shading, e: int, m: Moving, o: wp.vec3, d: wp.vec3,
                      s_a: float, s_b: float, j: int, n: int, la: wp.vec3, lm: wp.vec3, lb: wp.vec3) -> wp.vec3:
    """Radiance at boundary j of the n equal sub-pieces of [s_a, s_b] (the plan's samples where
    they fall there)."""
    if j == 0:
        return la
    if j == n:
        return lb
    if 2 * j == n:
        return lm
    return shade_at(view, geo, sh, e, m, o, d, s_a + (s_b - s_a) * float(j) / float(n))


@wp.func
def sub_piece_time(t: wp.vec2, j: int, n: int) -> float:
    """Shutter time of boundary j of the n equal sub-pieces of span t (exactly t[1] at j = n)."""
    if j >= n:
        return t[1]
    return t[0] + (t[1] - t[0]) * float(j) / float(n)


@wp.func
def lerp_in_time(r0: wp.vec3, r1: wp.vec3, t0: float, t1: float, time: float) -> wp.vec3:
    """Radiance at `time` of a piece spanning shutter times [t0, t1], linear from r0 to r1."""
    f = float(0.5)
    if t1 > t0:
        f = wp.clamp((time - t0) / (t1 - t0), 0.0, 1.0)
    return r0 + (r1 - r0) * f
