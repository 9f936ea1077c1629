"""Surface shading (SPEC §4) as Warp functions shared by every method.

Model: radiance = emissive + Σ_lights f(l, v) E_l cosθ + (diffuse + F0) · dome, where
f = diffuse/π + D·G·F / (4 cosθ_l cosθ_v) with GGX D (α = roughness²), Schlick-GGX G
(k = α/2) and Schlick F from F0. A shadowing light's term is multiplied by its shadow-map
visibility (shadow_lookup.py: mean over the light's samples, so area lights cast soft shadows);
the dome's ambient term is not shadowed. A material with black diffuse and black F0 returns its
emissive colour exactly, whatever the lights and the dome. Back faces are shaded with the
flipped normal, double- and single-sided alike (as Cycles, Karma and RenderMan shade a mesh seen
from behind; SPEC §4 changed by issue 19: a single-sided back face used to keep its front normal
and render dark). Cutout opacity is a hit test (cutout.py), not shading; fractional opacity is
ignored (rendered opaque, with a warning at load time).
"""

from __future__ import annotations

import warp as wp

from .kernel_types import Geometry, Shading, View
from .dome import dome_ambient
from .rays import entry_normal
from .light_table import light_value, light_vec
from .shadow_free import cell_of
from .shadow_lookup import light_taps_steady, light_visibility
from .texture_lookup import binding_output, binding_sample, binding_value

PI = wp.constant(3.14159265358979)


@wp.func
def max_component(c: wp.vec3) -> float:
    return wp.max(wp.max(c[0], c[1]), c[2])


@wp.func
def brdf(n: wp.vec3, v: wp.vec3, l: wp.vec3, diffuse: wp.vec3, f0: wp.vec3, roughness: float) -> wp.vec3:
    """Lambert + GGX microfacet BRDF (1/sr)."""
    nl = wp.dot(n, l)
    nv = wp.dot(n, v)
    result = diffuse / PI
    if nl > 0.0 and nv > 0.0 and wp.length_sq(f0) > 0.0:
        h = wp.normalize(l + v)
        # clamped to 1 too: unit vectors rounded in float32 can give a dot product just above 1,
        # where a smooth surface's GGX denominator nh² (a² - 1) + 1 cancels to 0 (an infinite pixel)
        nh = wp.clamp(wp.dot(n, h), 0.0, 1.0)
        vh = wp.clamp(wp.dot(v, h), 0.0, 1.0)
        a = roughness * roughness
        a2 = a * a
        den = nh * nh * (a2 - 1.0) + 1.0
        dist = a2 / (PI * den * den)
        k = a * 0.5
        g = (nl / (nl * (1.0 - k) + k)) * (nv / (nv * (1.0 - k) + k))
        # (1 - v·h)^5 by multiplication: a call to powf cost ~5% of a lit frame's CPU time
        x = 1.0 - vh
        x2 = x * x
        fw = x2 * x2 * x
        fres = f0 + (wp.vec3(1.0, 1.0, 1.0) - f0) * fw
        result = result + fres * (dist * g / (4.0 * nl * nv))
    return result


# inlined: an out-of-line Warp function receives its struct arguments by value (Shading is ~1 KB,
# copied per call and light)
@wp.func(inline=True)
def direct_light(sh: Shading, j: int, u: float, du: float, p: wp.vec3, vel: wp.vec3, n: wp.vec3, v: wp.vec3,
                 diffuse: wp.vec3, f0: wp.vec3, roughness: float, free: int) -> wp.vec3:
    """Reflected radiance from light j at camera-space point p (moving with velocity vel, units
    per shutter) with normal n, view vector v, at shutter time u (its shadow averaged over
    [u - du/2, u + du/2]). free: the receiver's shadow-free bits (bit j: no lookup needed)."""
    kind = int(sh.lights[0, j, 0])
    radiance = light_vec(sh, j, 1, u)
    out = wp.vec3(0.0, 0.0, 0.0)
    if kind == 0:
        l = wp.normalize(light_vec(sh, j, 7, u))
        cos_s = wp.dot(n, l)
        if cos_s > 0.0:
            out = wp.cw_mul(brdf(n, v, l, diffuse, f0, roughness), radiance) * cos_s
    elif kind == 1:
        r = light_value(sh, j, 16, u)
        r_eff = r
        if r_eff <= 0.0:
            r_eff = 0.5
        to_light = light_vec(sh, j, 4, u) - p
        dist2 = wp.max(wp.dot(to_light, to_light), 1.0e-12)
        l = to_light / wp.sqrt(dist2)
        cos_s = wp.dot(n, l)
        if cos_s > 0.0:
            e = PI * r_eff * r_eff / wp.max(dist2, r * r)
            out = wp.cw_mul(brdf(n, v, l, diffuse, f0, roughness), radiance) * (e * cos_s)
    else:
        center = light_vec(sh, j, 4, u)
        ln = wp.normalize(light_vec(sh, j, 7, u))
        hu = light_vec(sh, j, 10, u)
        hv = light_vec(sh, j, 13, u)
        area = 4.0 * wp.length(wp.cross(hu, hv))
        if kind == 3:
            area = PI * wp.length(wp.cross(hu, hv))
        for i in range(4):
            for k in range(4):
                su = (float(i) + 0.5) * 0.5 - 1.0
                sv = (float(k) + 0.5) * 0.5 - 1.0
                if kind == 3:  # concentric square -> disk map
                    rr = wp.max(wp.abs(su), wp.abs(sv))
                    phi = 0.0
                    if wp.abs(su) >= wp.abs(sv):
                        phi = (PI / 4.0) * (sv / su)
                    else:
                        phi = PI / 2.0 - (PI / 4.0) * (su / sv)
                    su = rr * wp.cos(phi)
                    sv = rr * wp.sin(phi)
                q = center + su * hu + sv * hv
                to_light = q - p
                dist2 = wp.max(wp.dot(to_light, to_light), 1.0e-12)
                l = to_light / wp.sqrt(dist2)
                cos_s = wp.dot(n, l)
                cos_l = -wp.dot(ln, l)
                if cos_s > 0.0 and cos_l > 0.0:
                    e = cos_l * area / (16.0 * dist2)
                    out = out + wp.cw_mul(brdf(n, v, l, diffuse, f0, roughness), radiance) * (e * cos_s)
    if max_component(out) > 0.0 and (j >= 31 or ((free >> j) & 1) == 0):
        out = out * light_visibility(sh, j, u, du, p, vel, n)
    return out


@wp.func(inline=True)
def entry_corners(geo: Geometry, e: int, vi: wp.vec3i, alpha: float):
    """(a, b, c, da, db, dc): entry e's corners (vertices vi) at interpolation alpha, as
    rays.entry_vertex gives them, and each one's change from knot k0 to k1 (zero for a static entry)."""
    p0 = geo.positions[geo.entry_k0[e], vi[0]]
    q0 = geo.positions[geo.entry_k0[e], vi[1]]
    r0 = geo.positions[geo.entry_k0[e], vi[2]]
    da = geo.positions[geo.entry_k1[e], vi[0]] - p0
    db = geo.positions[geo.entry_k1[e], vi[1]] - q0
    dc = geo.positions[geo.entry_k1[e], vi[2]] - r0
    return p0 + alpha * da, q0 + alpha * db, r0 + alpha * dc, da, db, dc


@wp.func
def entry_point_velocity(geo: Geometry, e: int, vi: wp.vec3i, hit: wp.vec4) -> wp.vec3:
    """Camera-space velocity (units per shutter) of the surface point of entry e at barycentrics
    (1 - w_b - w_c, w_b, w_c) = hit[2:4]: from its span's knots, or for a static entry from the
    sharp instant's vertex velocities when the geometry has them (else zero)."""
    _a, _b, _c, da, db, dc = entry_corners(geo, e, vi, 0.0)
    return corners_velocity(geo, e, vi, hit, da, db, dc)


@wp.func(inline=True)
def corners_velocity(geo: Geometry, e: int, vi: wp.vec3i, hit: wp.vec4, da: wp.vec3, db: wp.vec3,
                     dc: wp.vec3) -> wp.vec3:
    """entry_point_velocity with the corners' changes over the entry's span (da, db, dc: each
    vertex at k1 less at k0) given."""
    k0 = geo.entry_k0[e]
    k1 = geo.entry_k1[e]
    wb = hit[2]
    wc = hit[3]
    if k0 == k1:
        if geo.has_velocities == 0:
            return wp.vec3(0.0, 0.0, 0.0)
        return (1.0 - wb - wc) * geo.velocities[vi[0]] + wb * geo.velocities[vi[1]] + wc * geo.velocities[vi[2]]
    return ((1.0 - wb - wc) * da + wb * db + wc * dc) * (float(geo.num_segments) / float(k1 - k0))


@wp.func
def normal_mapped(geo: Geometry, sh: Shading, tri: int, binding: int, a: wp.vec3, b: wp.vec3, c: wp.vec3,
                  n: wp.vec3, wb: float, wc: float) -> wp.vec3:
    """The shading normal n perturbed by a tangent-space normal map (UsdPreviewSurface `normal`:
    the binding's value after scale and bias, x along +s, y along +t, z along n), with the
    tangent frame from triangle tri's corner positions a, b, c and texture coordinates,
    orthogonalised against n. A triangle whose coordinates are degenerate keeps n."""
    uv0 = geo.tri_uvs[3 * tri]
    uv1 = geo.tri_uvs[3 * tri + 1]
    uv2 = geo.tri_uvs[3 * tri + 2]
    e1 = b - a
    e2 = c - a
    du1 = uv1[0] - uv0[0]
    dv1 = uv1[1] - uv0[1]
    du2 = uv2[0] - uv0[0]
    dv2 = uv2[1] - uv0[1]
    det = du1 * dv2 - du2 * dv1
    if det == 0.0:
        return n
    t = (e1 * dv2 - e2 * dv1) / det
    bt = (e2 * du1 - e1 * du2) / det
    t = t - n * wp.dot(n, t)
    if wp.length(t) == 0.0:
        return n
    t = wp.normalize(t)
    bt = bt - n * wp.dot(n, bt) - t * wp.dot(t, bt)
    if wp.length(bt) == 0.0:
        return n
    bt = wp.normalize(bt)
    uv = (1.0 - wb - wc) * uv0 + wb * uv1 + wc * uv2
    tn = binding_value(sh.tex, binding, uv, geo.tri_lod[tri])
    p = tn[0] * t + tn[1] * bt + tn[2] * n
    if wp.length(p) == 0.0 or wp.dot(p, n) <= 0.0:
        return n
    return wp.normalize(p)


@wp.func(inline=True)
def view_vector(view: View, p: wp.vec3) -> wp.vec3:
    """Unit vector from camera-space point p towards the eye."""
    if view.ortho == 0:
        return wp.normalize(-p)
    return wp.vec3(0.0, 0.0, 1.0)


# inlined: shade_entry_hit_span's own code before it was shared (no call per shading)
@wp.func(inline=True)
def surface_normal(geo: Geometry, sh: Shading, e: int, alpha: float, v: wp.vec3, hit: wp.vec4) -> wp.vec3:
    """The shading normal at the hit of entry e (interpolation alpha, barycentrics hit[2:4]):
    interpolated vertex normals where the triangle has them, else its face normal, perturbed by
    its material's normal map, turned towards the view vector v's side of the face."""
    a, b, c, _da, _db, _dc = entry_corners(geo, e, geo.tri_vertices[geo.entry_tri[e]], alpha)
    return corners_normal(geo, sh, e, alpha, a, b, c, v, hit)


@wp.func(inline=True)
def corners_normal(geo: Geometry, sh: Shading, e: int, alpha: float, a: wp.vec3, b: wp.vec3, c: wp.vec3, v: wp.vec3,
                   hit: wp.vec4) -> wp.vec3:
    """surface_normal with the triangle's corners at alpha (a, b, c: entry_corners') given."""
    tri = geo.entry_tri[e]
    m = geo.tri_material[tri]
    wb = hit[2]
    wc = hit[3]
    vi = geo.tri_vertices[tri]
    ng = wp.normalize(wp.cross(b - a, c - a))
    flags = geo.tri_flags[tri]
    n = ng
    if (flags & 2) != 0:
        ns = (1.0 - wb - wc) * entry_normal(geo, e, vi[0], alpha) + wb * entry_normal(geo, e, vi[1], alpha) + wc * entry_normal(geo, e, vi[2], alpha)
        if wp.length_sq(ns) > 0.0:
            n = wp.normalize(ns)
    if sh.materials[m, 22] >= 0.0 and geo.tri_uvs.shape[0] >= 3 * tri + 3:
        n = normal_mapped(geo, sh, tri, int(sh.materials[m, 22]), a, b, c, n, wb, wc)
    if wp.dot(ng, v) < 0.0:
        n = -n
    return n


@wp.func
def shadows_steady_at(view: View, geo: Geometry, sh: Shading, e: int, u: float, o: wp.vec3, d: wp.vec3,
                      hit: wp.vec4) -> bool:
    """True when every shadowing light's lookup from the hit of static entry e reads, at time u,
    only texels that never change over the frame's map instants (the flags in sh.shadow_varying,
    when they are the maps' own: shape (slots, S, S)); under lights that hold still, the hit's
    radiance is then the same at every instant."""
    if sh.shadow_varying.shape[1] != sh.shadow_size or sh.shadow_times <= 1:
        return False
    p = o + d * hit[1]
    n = surface_normal(geo, sh, e, 0.0, view_vector(view, p), hit)
    for j in range(sh.num_lights):
        if sh.shadow_lights[j, 0] >= 0:
            # one texel of margin: the lookups use the light's frame tabled per map instant
            if not light_taps_steady(sh, j, u, p, n, 1):
                return False
    return True


@wp.func
def shade_entry_hit(view: View, geo: Geometry, sh: Shading, e: int, alpha: float, u: float,
                    o: wp.vec3, d: wp.vec3, hit: wp.vec4) -> wp.vec3:
    """Radiance leaving the hit point of entry e (at interpolation alpha, shutter time u)."""
    return shade_entry_hit_span(view, geo, sh, e, alpha, u, 0.0, o, d, hit)


@wp.func(inline=True)
def shade_entry_hit_span(view: View, geo: Geometry, sh: Shading, e: int, alpha: float, u: float, du: float,
                         o: wp.vec3, d: wp.vec3, hit: wp.vec4) -> wp.vec3:
    """Radiance leaving the hit point of entry e (at interpolation alpha, shutter time u), with
    shadows averaged over the shutter span [u - du/2, u + du/2] that the caller stands it for."""
    a, b, c, da, db, dc = entry_corners(geo, e, geo.tri_vertices[geo.entry_tri[e]], alpha)
    return shade_corners_span(view, geo, sh, e, alpha, a, b, c, da, db, dc, u, du, o, d, hit)


@wp.func
def shade_corners_span(view: View, geo: Geometry, sh: Shading, e: int, alpha: float, a: wp.vec3, b: wp.vec3,
                       c: wp.vec3, da: wp.vec3, db: wp.vec3, dc: wp.vec3, u: float, du: float, o: wp.vec3,
                       d: wp.vec3, hit: wp.vec4) -> wp.vec3:
    """shade_entry_hit_span with the triangle's corners at alpha (a, b, c: entry_corners') and
    their changes over the entry's span (da, db, dc) given: the analytic resolve has them already
    (radiance.radiance_at)."""
    tri = geo.entry_tri[e]
    m = geo.tri_material[tri]
    emissive = wp.vec3(sh.materials[m, 3], sh.materials[m, 4], sh.materials[m, 5])
    diffuse = wp.vec3(sh.materials[m, 0], sh.materials[m, 1], sh.materials[m, 2])
    wb = hit[2]
    wc = hit[3]
    if sh.materials[m, 10] > 0.5:
        diffuse = (1.0 - wb - wc) * geo.tri_colors[3 * tri] + wb * geo.tri_colors[3 * tri + 1] + wc * geo.tri_colors[3 * tri + 2]
    f0 = wp.vec3(sh.materials[m, 6], sh.materials[m, 7], sh.materials[m, 8])
    roughness = sh.materials[m, 9]
    if sh.materials[m, 21] > 0.5:   # textured: inputs per hit, then UsdPreviewSurface's metallic mix
        uv = wp.vec2(0.0, 0.0)
        lod = float(-30.0)
        if geo.tri_uvs.shape[0] >= 3 * tri + 3:
            uv = (1.0 - wb - wc) * geo.tri_uvs[3 * tri] + wb * geo.tri_uvs[3 * tri + 1] + wc * geo.tri_uvs[3 * tri + 2]
            lod = geo.tri_lod[tri]
        if sh.materials[m, 12] >= 0.0:
            diffuse = binding_value(sh.tex, int(sh.materials[m, 12]), uv, lod)
        if sh.materials[m, 13] >= 0.0:
            emissive = binding_value(sh.tex, int(sh.materials[m, 13]), uv, lod)
        b_rough = int(sh.materials[m, 14])
        b_metal = int(sh.materials[m, 15])
        metallic = sh.materials[m, 19]
        if sh.materials[m, 23] > 0.5:
            # one texture read for both (a metallic-roughness texture): the same sample, two channels
            texel = binding_sample(sh.tex, b_rough, uv, lod)
            roughness = wp.clamp(binding_output(sh.tex, b_rough, texel)[0], 0.02, 1.0)
            metallic = wp.clamp(binding_output(sh.tex, b_metal, texel)[0], 0.0, 1.0)
        else:
            if b_rough >= 0:
                roughness = wp.clamp(binding_value(sh.tex, b_rough, uv, lod)[0], 0.02, 1.0)
            if b_metal >= 0:
                metallic = wp.clamp(binding_value(sh.tex, b_metal, uv, lod)[0], 0.0, 1.0)
        if sh.materials[m, 17] > 0.5:
            dielectric = sh.materials[m, 18]
            f0 = (1.0 - metallic) * wp.vec3(dielectric, dielectric, dielectric) + metallic * diffuse
            diffuse = diffuse * (1.0 - metallic)
    if wp.length_sq(diffuse) == 0.0 and wp.length_sq(f0) == 0.0:
        return emissive
    vi = geo.tri_vertices[tri]
    p = o + d * hit[1]
    v = view_vector(view, p)
    n = corners_normal(geo, sh, e, alpha, a, b, c, v, hit)
    out = emissive + wp.cw_mul(diffuse, dome_ambient(sh, n)) + wp.cw_mul(f0, sh.dome)
    vel = corners_velocity(geo, e, vi, hit, da, db, dc)
    # lights whose shadows cannot fall on this part of the entry (shadow_free.py): no lookup
    free = int(0)
    if geo.shadow_free.shape[0] >= (e + 1) * sh.num_lights:
        cell = cell_of(hit[2], hit[3])
        for j in range(wp.min(sh.num_lights, 31)):
            free = free | (((geo.shadow_free[e * sh.num_lights + j] >> cell) & 1) << j)
    for j in range(sh.num_lights):
        out = out + direct_light(sh, j, u, du, p, vel, n, v, diffuse, f0, roughness, free)
    return out
