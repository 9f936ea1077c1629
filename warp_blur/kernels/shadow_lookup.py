"""Shadow-map lookups in shading (@wp.func only): depth comparison with bias and percentage-closer
filtering, averaged over a light's samples and interpolated between the maps' instants.

A *face* is one depth image seen from a light: orthographic (distant lights) or perspective
(one fitted frustum, or the six faces of a cube). Its row in `Shading.shadow_faces` holds the
face's rotation in the light's local frame (rows 0-8), the light sample's offset in that frame
(9-11), the window (12-15: x0, y0, x1, y1 on the plane at distance 1, or in scene units when
orthographic), the ortho flag (16), the near depth (17), the cube flag (18: a cube face,
whose rows are signed unit axes and whose window is square about its axis; see face_coords), and
the window's scales (19, 20: texels per window unit in x and y; 21: window units per texel).
face_from_cam is built at the lookup's own time from the light table (the light's frame in camera
space then), so a moving camera never shifts a shadow: maps are rigid with the light. Texel (i, j) of an S×S face covers window x in
[x0 + i (x1-x0)/S, ...], y measured downwards from y1, as camera pixels are.

Layout: a light's face slot (first + m F + f for sample m, face f) is read as
shadow_maps[slot, y, x, b] for map instant b. Where a pixel is shaded at many times (stochastic,
analytic) the memory holds each texel's instants side by side, so a lookup between two instants
and the lookups of neighbouring samples at other times read the same cache lines; for a sharp
instant (accumulation), which reads one or two map instants, it holds each instant's image whole
(a strided view, device_data.shadow_map_array), so the texels a pass reads stay in cache.

Comparisons are averaged, never depths: a light's visibility at time u is the PCF comparison
averaged over its M samples, linearly interpolated between the two maps whose instants bracket u
(maps sit at (b + 0.5)/B of the shutter). Where shadow_nearest is set (stochastic) it is the
nearest map's value instead: over the random times of a pixel's samples both average to the same
shutter mean, and the nearest takes one lookup where a moving light's blend takes two. Over a time
span it is the mean of point values, or one point value where the light holds still and the
texels read never change (shadow_varying).
"""

from __future__ import annotations

import warp as wp

from .kernel_types import Shading
from .light_table import light_vec

FACE_WIDTH = 22
#: receiver points this close (relative) in two maps' light frames are one point: float32
#: rounding of a world-still point seen from a moving camera, far below a texel
SAME_POINT_TOL = wp.constant(1.0e-5)


@wp.func
def light_axes(sh: Shading, j: int, u: float) -> wp.mat33:
    """Rows: light j's local x, y, z axes in camera space at shutter time u."""
    x = wp.normalize(light_vec(sh, j, 10, u))
    y = light_vec(sh, j, 13, u)
    y = wp.normalize(y - wp.dot(y, x) * x)
    z = wp.cross(x, y)
    return wp.mat33(x[0], x[1], x[2], y[0], y[1], y[2], z[0], z[1], z[2])


@wp.func
def face_rotation(sh: Shading, f: int) -> wp.mat33:
    r = sh.shadow_faces
    return wp.mat33(r[f, 0], r[f, 1], r[f, 2], r[f, 3], r[f, 4], r[f, 5], r[f, 6], r[f, 7], r[f, 8])


@wp.func
def texel_lit(maps: wp.array4d(dtype=float), f: int, i: int, j: int, b0: int, b1: int, frac: float,
              depth: float) -> float:
    """Depth comparison at texel (i, j) (within the face) of face slot f, blended between map
    instants b0 and b1 (weight frac of b1; the two are adjacent in memory). The maps are passed
    rather than the Shading struct, so their pointer and strides are read once per lookup."""
    lit = float(0.0)
    if depth <= maps[f, j, i, b0]:
        lit = 1.0
    if frac > 0.0:
        lit1 = float(0.0)
        if depth <= maps[f, j, i, b1]:
            lit1 = 1.0
        lit = lit + frac * (lit1 - lit)
    return lit


@wp.func
def bilinear_lit(maps: wp.array4d(dtype=float), s: int, f: int, fx: float, fy: float, b0: int, b1: int,
                 frac: float, depth: float) -> float:
    """The 2x2 bilinear tap of depth comparisons at continuous texel coordinates (fx, fy) (texel
    centres at integers; taps outside the face clamp to its edge)."""
    i = int(wp.floor(fx))
    j = int(wp.floor(fy))
    ax = fx - float(i)
    ay = fy - float(j)
    i0 = wp.clamp(i, 0, s - 1)
    i1 = wp.clamp(i + 1, 0, s - 1)
    j0 = wp.clamp(j, 0, s - 1)
    j1 = wp.clamp(j + 1, 0, s - 1)
    total = (1.0 - ax) * (1.0 - ay) * texel_lit(maps, f, i0, j0, b0, b1, frac, depth)
    total += ax * (1.0 - ay) * texel_lit(maps, f, i1, j0, b0, b1, frac, depth)
    total += (1.0 - ax) * ay * texel_lit(maps, f, i0, j1, b0, b1, frac, depth)
    total += ax * ay * texel_lit(maps, f, i1, j1, b0, b1, frac, depth)
    return total


@wp.func
def face_coords(sh: Shading, f: int, pl: wp.vec3, nl: wp.vec3) -> wp.vec4:
    """(texel x, texel y, biased depth, 1) of a receiver point pl with normal nl (facing the
    light), both in the light's local frame (light_local), in face f; w = 0 when the point is
    outside the face. Texel coordinates are continuous, texel centres at integers (bilinear taps
    at floor and floor + 1). One division: the window tests compare against the window scaled by
    the depth (positive in a perspective face), and the face's scales are tabled (19-21)."""
    r = sh.shadow_faces
    rel = pl - wp.vec3(r[f, 9], r[f, 10], r[f, 11])
    # depth first: a cube face behind the point is rejected before the rest of the transform
    depth = -(r[f, 6] * rel[0] + r[f, 7] * rel[1] + r[f, 8] * rel[2])
    ortho = r[f, 16] > 0.5
    scale = float(1.0)
    if not ortho:
        if depth <= r[f, 17]:
            return wp.vec4(0.0, 0.0, 0.0, 0.0)
        scale = depth
    if r[f, 18] > 0.5:
        # a cube face: the rotated coordinates are the other two of rel up to sign, so the window
        # test below rejects exactly when the largest |component| passes the window at that depth
        # (depth itself is one of them and never does); decided before the rotation is loaded
        big = wp.max(wp.max(wp.abs(rel[0]), wp.abs(rel[1])), wp.abs(rel[2]))
        if big > r[f, 14] * depth:
            return wp.vec4(0.0, 0.0, 0.0, 0.0)
    a = face_rotation(sh, f)
    q = a * rel
    x0 = r[f, 12]
    y0 = r[f, 13]
    x1 = r[f, 14]
    y1 = r[f, 15]
    if q[0] < x0 * scale or q[0] > x1 * scale or q[1] < y0 * scale or q[1] > y1 * scale:
        return wp.vec4(0.0, 0.0, 0.0, 0.0)
    texel = r[f, 21] * scale
    # normal offset, then a constant bias, both in texels at the receiver
    qn = q + (a * nl) * (sh.shadow_normal_bias * texel)
    depth = -qn[2] - sh.shadow_bias * texel
    wx = qn[0]
    wy = qn[1]
    if not ortho:
        inv = 1.0 / wp.max(-qn[2], r[f, 17])
        wx = qn[0] * inv
        wy = qn[1] * inv
    return wp.vec4((wx - x0) * r[f, 19] - 0.5, (y1 - wy) * r[f, 20] - 0.5, depth, 1.0)


@wp.func
def coords_visibility(sh: Shading, f: int, c: wp.vec4, b0: int, b1: int, frac: float) -> float:
    """Visibility at face coordinates c (face_coords' texel x, texel y and biased depth) of face
    slot f: the PCF of depth comparisons there, at instant b0 blended with b1 by frac, in [0, 1]."""
    depth = c[2]
    maps = sh.shadow_maps
    size = sh.shadow_size
    r = sh.shadow_pcf
    if r == 0:
        return bilinear_lit(maps, size, f, c[0], c[1], b0, b1, frac, depth)
    total = float(0.0)
    for dy in range(-r, r + 1):
        for dx in range(-r, r + 1):
            total += bilinear_lit(maps, size, f, c[0] + float(dx), c[1] + float(dy), b0, b1, frac, depth)
    return total / float((2 * r + 1) * (2 * r + 1))


@wp.func
def face_steady(sh: Shading, f: int, pl: wp.vec3, nl: wp.vec3, margin: int) -> int:
    """1 when the lookup of light-local point pl in face f reads only texels whose depth is the
    same at every instant (and so do those within `margin` texels of them), 0 when one varies, -1
    when the point is outside the face."""
    c = face_coords(sh, f, pl, nl)
    if c[3] == 0.0:
        return -1
    return coords_steady(sh, f, c, margin)


@wp.func
def coords_steady(sh: Shading, f: int, c: wp.vec4, margin: int) -> int:
    """face_steady at face coordinates c of face slot f (1 steady, 0 a texel varies)."""
    s = sh.shadow_size
    r = sh.shadow_pcf + margin
    i0 = int(wp.floor(c[0]))
    j0 = int(wp.floor(c[1]))
    for j in range(j0 - r, j0 + r + 2):
        for i in range(i0 - r, i0 + r + 2):
            if sh.shadow_varying[f, wp.clamp(j, 0, s - 1), wp.clamp(i, 0, s - 1)] != wp.uint8(0):
                return 0
    return 1


@wp.func
def light_taps_steady(sh: Shading, j: int, u: float, p: wp.vec3, n: wp.vec3, margin: int) -> bool:
    """True when every sample's lookup of light j (its frame at time u) from p, normal n, reads
    only texels whose depth is the same in all the maps' instants (sh.shadow_varying), and so do
    those within `margin` texels of them (room for rounding between frames computed apart)."""
    first = sh.shadow_lights[j, 0]
    num_faces = sh.shadow_lights[j, 2]
    axes = light_axes(sh, j, u)
    pl = axes * (p - light_vec(sh, j, 4, u))
    nl = axes * n
    for m in range(sh.shadow_lights[j, 1]):
        base = first + m * num_faces
        for f in range(num_faces):
            st = face_steady(sh, base + f, pl, nl, margin)
            if st == 0:
                return False
            if st == 1:
                break
    return True


@wp.func
def containing_face(sh: Shading, first_face: int, num_faces: int, pl: wp.vec3, nl: wp.vec3):
    """(face slot, face_coords there) of the first face of a light sample's map (faces first_face
    onwards) that contains light-local point pl (normal nl); (-1, zero) when none does."""
    for f in range(num_faces):
        c = face_coords(sh, first_face + f, pl, nl)
        if c[3] != 0.0:
            return first_face + f, c
    return int(-1), wp.vec4(0.0, 0.0, 0.0, 0.0)


@wp.func
def map_visibility(sh: Shading, first_face: int, num_faces: int, b0: int, b1: int, frac: float, pl: wp.vec3,
                   nl: wp.vec3) -> float:
    """Visibility of light-local point pl (normal nl) in the first face of a light sample's map
    that contains it, at instant b0 blended with b1 by frac (lit when no face contains it:
    nothing that casts a shadow was there)."""
    face, c = containing_face(sh, first_face, num_faces, pl, nl)
    if face < 0:
        return 1.0
    return coords_visibility(sh, face, c, b0, b1, frac)


@wp.func
def instant_frame(sh: Shading, j: int, b: int):
    """(axes, origin) of light j at map instant b (times > 1), as light_axes and light_vec give
    them at that instant (tabled by the host: one row of 12 per light and instant)."""
    r = sh.shadow_frames
    k = j * sh.shadow_times + b
    return (wp.mat33(r[k, 0], r[k, 1], r[k, 2], r[k, 3], r[k, 4], r[k, 5], r[k, 6], r[k, 7], r[k, 8]),
            wp.vec3(r[k, 9], r[k, 10], r[k, 11]))


@wp.func
def map_instant(sh: Shading, b: int, u: float) -> float:
    """Shutter time of map instant b (maps at (b + 0.5)/times; a single map stands for u itself)."""
    if sh.shadow_times > 1:
        return (float(b) + 0.5) / float(sh.shadow_times)
    return u


@wp.func
def bracket_instants(sh: Shading, u: float):
    """(b0, b1, frac): the map instants whose times bracket shutter time u and the weight of b1
    (the nearest instant alone, frac 0, where shadow_nearest is set; 0, 0, 0 for a single map)."""
    times = sh.shadow_times
    b0 = int(0)
    b1 = int(0)
    frac = float(0.0)
    if times > 1:
        x = wp.clamp(u, 0.0, 1.0) * float(times) - 0.5
        b0 = wp.clamp(int(wp.floor(x)), 0, times - 1)
        b1 = wp.min(b0 + 1, times - 1)
        frac = wp.clamp(x - float(b0), 0.0, 1.0)
        if sh.shadow_nearest != 0:
            if frac >= 0.5:
                b0 = b1
            b1 = b0
            frac = 0.0
    return b0, b1, frac


@wp.func
def still_span_visibility(sh: Shading, j: int, u: float, du: float, steps: int, p: wp.vec3, n: wp.vec3) -> float:
    """light_visibility over [u - du/2, u + du/2] in `steps` lookups, where light j holds still
    and so does the receiver point p (normal n): every step reads each sample's map at the same
    face and texel coordinates, found once here; only the map instants change. Texels that never
    vary there (every sample): one lookup, at the first map's instant. Each step's value is the
    one light_visibility_at gives; they are summed sample by sample (the same sum in another
    order: equal for one light sample, to rounding for several)."""
    first = sh.shadow_lights[j, 0]
    num_samples = sh.shadow_lights[j, 1]
    num_faces = sh.shadow_lights[j, 2]
    axes, origin = instant_frame(sh, j, 0)
    pl = axes * (p - origin)
    nl = axes * n
    steady_total = float(0.0)
    span_total = float(0.0)
    steady = int(1)
    for m in range(num_samples):
        face, c = containing_face(sh, first + m * num_faces, num_faces, pl, nl)
        if face < 0:
            # in no face: nothing that casts a shadow was there, lit at every instant
            steady_total += 1.0
            span_total += float(steps)
        else:
            v0 = coords_visibility(sh, face, c, 0, 0, 0.0)
            steady_total += v0
            if coords_steady(sh, face, c, 0) == 1:
                span_total += float(steps) * v0
            else:
                steady = 0
                for i in range(steps):
                    ui = u - 0.5 * du + du * (float(i) + 0.5) / float(steps)
                    b0, b1, frac = bracket_instants(sh, ui)
                    span_total += coords_visibility(sh, face, c, b0, b1, frac)
    if steady != 0:
        return steady_total / float(num_samples)
    return span_total / (float(num_samples) * float(steps))


@wp.func
def light_visibility_at(sh: Shading, j: int, u: float, p: wp.vec3, vel: wp.vec3, n: wp.vec3) -> float:
    """Visibility of light j from p at shutter time u: mean over the light's samples, linear in
    time between the maps' instants. Each map is read as of its own instant: the light's frame
    then, and the receiver point moved there with its velocity vel (camera-space units per
    shutter), so a moving surface is never shadowed by where it was (or will be) itself."""
    first = sh.shadow_lights[j, 0]
    if first < 0:
        return 1.0
    num_samples = sh.shadow_lights[j, 1]
    num_faces = sh.shadow_lights[j, 2]
    times = sh.shadow_times
    b0, b1, frac = bracket_instants(sh, u)
    t0 = map_instant(sh, b0, u)
    t1 = map_instant(sh, b1, u)
    blend = frac > 0.0 and b1 != b0
    axes0 = wp.mat33()
    origin0 = wp.vec3()
    if times > 1:   # the light's frame at each map instant, tabled on the host
        axes0, origin0 = instant_frame(sh, j, b0)
    else:
        axes0 = light_axes(sh, j, t0)
        origin0 = light_vec(sh, j, 4, t0)
    # the receiver in the light's frame at each map's instant, once for all samples and faces
    # (the second instant's only when blending: b1 != b0 implies times > 1)
    pl0 = axes0 * (p + (t0 - u) * vel - origin0)
    nl0 = axes0 * n
    pl1 = pl0
    nl1 = nl0
    together = False
    if blend:
        axes1, origin1 = instant_frame(sh, j, b1)
        pl1 = axes1 * (p + (t1 - u) * vel - origin1)
        nl1 = axes1 * n
        # the same point in both maps (a light that holds still over a receiver that does, in the
        # world, even where the camera moves: equal to rounding): one pass reads both instants'
        # texels, which sit side by side
        together = wp.length(pl0 - pl1) <= SAME_POINT_TOL * wp.max(wp.length(pl0), 1.0)
    total = float(0.0)
    for m in range(num_samples):
        slot = first + m * num_faces
        if together:
            total += map_visibility(sh, slot, num_faces, b0, b1, frac, pl0, nl0)
        else:
            v = map_visibility(sh, slot, num_faces, b0, b0, 0.0, pl0, nl0)
            if blend:
                v1 = map_visibility(sh, slot, num_faces, b1, b1, 0.0, pl1, nl1)
                v = v + frac * (v1 - v)
            total += v
    return total / float(num_samples)


@wp.func
def light_visibility(sh: Shading, j: int, u: float, du: float, p: wp.vec3, vel: wp.vec3, n: wp.vec3) -> float:
    """Mean visibility of light j over shutter times [u - du/2, u + du/2] (du = 0: the instant u)
    from receiver point p (at u, moving with velocity vel), sampled once per map instant the span
    covers."""
    if sh.shadow_lights[j, 0] < 0:
        return 1.0
    steps = int(1)
    if du > 0.0 and sh.shadow_times > 1:
        steps = wp.clamp(int(wp.ceil(du * float(sh.shadow_times))), 1, sh.shadow_times)
    if steps == 1:
        return light_visibility_at(sh, j, u, p, vel, n)
    if wp.length(vel) == 0.0 and sh.shadow_lights[j, 3] == 1:
        # light and receiver hold still: the lookups differ only in their map instants
        return still_span_visibility(sh, j, u, du, steps, p, n)
    total = float(0.0)
    for i in range(steps):
        ui = u - 0.5 * du + du * (float(i) + 0.5) / float(steps)
        total += light_visibility_at(sh, j, ui, p + (ui - u) * vel, vel, n)
    return total / float(steps)
