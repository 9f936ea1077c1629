"""Parts of entries no shadow can fall on (kernels): a light's lookups from such a part read only
texels where nothing casts a shadow, at every map instant, so they are lit (1) and shading skips
them.

Most of a lit frame's lookups come from receivers far from any shadow (a ground in the sun): each
lookup is a serial chain of loads and a transform (~25-150 ns), and nothing in its result depends
on the receiver there. A conservative test per entry and light decides it once a frame:
the blocks of each face slot's texels that hold a depth at any instant are marked (by the maps
as they are written, shadows/texel_major.py, or else by `block_occupancy`; a summed-area table
over them is built on the host), and `entry_shadow_free` projects the
entry's triangle, carried to each map instant, into each face as shadow_lookup.face_coords
projects a receiver point, widens its box by every offset a lookup adds (normal offset, bilinear
taps, PCF, a texel for rounding) and asks the table whether any block in it is occupied. A
triangle whose box is wide and at most half occupied is tested again in CELLS (CELLS + 1) / 2
barycentric cells, one bit each (cell_of), so a ground cell beside a shadow is flagged in parts.
"""

from __future__ import annotations

import warp as wp

from .kernel_types import Geometry, Shading
from .light_table import light_vec
from .shadow_lookup import face_rotation, instant_frame, light_axes

#: barycentric cells per triangle side: an entry's points are flagged in CELLS (CELLS + 1) / 2 parts
CELLS = wp.constant(4)
ALL_CELLS = wp.constant((1 << 16) - 1)


@wp.kernel(enable_backward=False)
def block_occupancy(maps: wp.array4d(dtype=float), block: int, bands: int, first: int,
                    occupied: wp.array3d(dtype=int)):
    """occupied[slot, by, bx] = 1 where a texel of block (bx, by) (block × block texels) of face
    slot holds anything but +inf (a caster's depth) at some map instant; left 0 elsewhere. One
    thread per band of `block` texel rows of a slot (flat index first + tid), each texel's
    instants read together. maps: (slots, S, S, B) indexed [slot, y, x, instant], in either
    memory layout."""
    k = first + wp.tid()
    s = k // bands
    by = k % bands
    size = maps.shape[1]
    y0 = by * block
    y1 = wp.min(y0 + block, size)
    for y in range(y0, y1):
        for x in range(size):
            for b in range(maps.shape[3]):
                if not (maps[s, y, x, b] == wp.inf):   # a depth, or a NaN: occupied
                    occupied[s, by, x // block] = 1


@wp.func
def window_point(sh: Shading, f: int, pl: wp.vec3) -> wp.vec3:
    """(window x, window y, depth) of light-local point pl in face slot f, before any bias, as
    face_coords computes them (depth along the face's view axis; perspective faces divide by it)."""
    r = sh.shadow_faces
    rel = pl - wp.vec3(r[f, 9], r[f, 10], r[f, 11])
    q = face_rotation(sh, f) * rel
    depth = -q[2]
    if r[f, 16] > 0.5:
        return wp.vec3(q[0], q[1], depth)
    if depth > 0.0:
        return wp.vec3(q[0] / depth, q[1] / depth, depth)
    return wp.vec3(0.0, 0.0, depth)


#: face_test's answers
FREE = wp.constant(1)
OCCUPIED = wp.constant(0)
OCCUPIED_WIDE = wp.constant(2)   # occupied in at most half of a box over two blocks across: parts may be free


@wp.func
def face_test(sh: Shading, f: int, a: wp.vec3, b: wp.vec3, c: wp.vec3, d: wp.vec3, occ: wp.array3d(dtype=int),
              block: int) -> int:
    """FREE when no lookup of a point of the convex polygon (a, b, c, d) (light-local; d = c for a
    triangle) in face slot f can read a texel that holds a depth (occ: summed-area tables of each
    slot's blocks occupied at any instant), else OCCUPIED or OCCUPIED_WIDE."""
    r = sh.shadow_faces
    ortho = r[f, 16] > 0.5
    near = r[f, 17]
    # the normal offset: nb texels, a texel being r21 window units (times the depth if perspective)
    eps = sh.shadow_normal_bias * r[f, 21]
    x0 = r[f, 12]
    y0 = r[f, 13]
    x1 = r[f, 14]
    y1 = r[f, 15]
    pa = window_point(sh, f, a)
    pb = window_point(sh, f, b)
    pc = window_point(sh, f, c)
    pd = window_point(sh, f, d)
    size = sh.shadow_size
    whole = False
    shift = eps
    if not ortho:
        dmax = wp.max(wp.max(pa[2], pb[2]), wp.max(pc[2], pd[2]))
        dmin = wp.min(wp.min(pa[2], pb[2]), wp.min(pc[2], pd[2]))
        if not (dmax > near):
            return FREE   # every point of it lies behind the near plane: the face never takes it
        if eps >= 0.5 or not (dmin * (1.0 - eps) > near):
            whole = True   # it crosses the near plane: any texel of the face
        else:
            # an offset of at most eps * depth moves the projection by eps (1 + |w|) / (1 - eps)
            big = wp.max(wp.max(wp.abs(x0), wp.abs(x1)), wp.max(wp.abs(y0), wp.abs(y1)))
            shift = eps * (1.0 + big) / (1.0 - eps)
    ix0 = int(0)
    iy0 = int(0)
    ix1 = size - 1
    iy1 = size - 1
    if not whole:
        lo_x = wp.min(wp.min(pa[0], pb[0]), wp.min(pc[0], pd[0]))
        hi_x = wp.max(wp.max(pa[0], pb[0]), wp.max(pc[0], pd[0]))
        lo_y = wp.min(wp.min(pa[1], pb[1]), wp.min(pc[1], pd[1]))
        hi_y = wp.max(wp.max(pa[1], pb[1]), wp.max(pc[1], pd[1]))
        if not (lo_x <= hi_x and lo_y <= hi_y and wp.abs(lo_x) < 1.0e30 and wp.abs(hi_x) < 1.0e30
                and wp.abs(lo_y) < 1.0e30 and wp.abs(hi_y) < 1.0e30):
            return OCCUPIED   # not finite: nothing known
        if hi_x < x0 or lo_x > x1 or hi_y < y0 or lo_y > y1:
            return FREE    # outside the window: the face never takes a point of it
        # the points the face takes lie in the window; each lookup's point may move by shift
        lo_x = wp.max(lo_x, x0) - shift
        hi_x = wp.min(hi_x, x1) + shift
        lo_y = wp.max(lo_y, y0) - shift
        hi_y = wp.min(hi_y, y1) + shift
        # texel coordinates as face_coords makes them; the 2x2 taps at floor and floor + 1, the
        # PCF radius around them, and a texel for rounding on each side
        pad = sh.shadow_pcf + 1
        fx0 = (lo_x - x0) * r[f, 19] - 0.5
        fx1 = (hi_x - x0) * r[f, 19] - 0.5
        fy0 = (y1 - hi_y) * r[f, 20] - 0.5
        fy1 = (y1 - lo_y) * r[f, 20] - 0.5
        lim = float(4 * size)
        ix0 = wp.max(int(wp.floor(wp.clamp(fx0, -lim, lim))) - pad, 0)
        ix1 = wp.min(int(wp.floor(wp.clamp(fx1, -lim, lim))) + 1 + pad, size - 1)
        iy0 = wp.max(int(wp.floor(wp.clamp(fy0, -lim, lim))) - pad, 0)
        iy1 = wp.min(int(wp.floor(wp.clamp(fy1, -lim, lim))) + 1 + pad, size - 1)
        if ix0 > ix1 or iy0 > iy1:
            # clamped taps read the edge texels
            ix0 = wp.clamp(ix0, 0, size - 1)
            ix1 = wp.clamp(ix1, ix0, size - 1)
            iy0 = wp.clamp(iy0, 0, size - 1)
            iy1 = wp.clamp(iy1, iy0, size - 1)
    bx0 = ix0 // block
    bx1 = ix1 // block + 1
    by0 = iy0 // block
    by1 = iy1 // block + 1
    count = occ[f, by1, bx1] - occ[f, by0, bx1] - occ[f, by1, bx0] + occ[f, by0, bx0]
    if count == 0:
        return FREE
    # wide and at most half occupied: parts of it may be free (worth testing cell by cell)
    if not whole and (bx1 - bx0 > 2 or by1 - by0 > 2) and 2 * count <= (bx1 - bx0) * (by1 - by0):
        return OCCUPIED_WIDE
    return OCCUPIED


@wp.func
def extrapolated(geo: Geometry, e: int, v: int, u: float) -> wp.vec3:
    """Vertex v of entry e carried linearly to shutter time u along its span's motion (as a
    receiver point is carried to a map's instant with its velocity: shading.entry_point_velocity)."""
    k0 = geo.entry_k0[e]
    k1 = geo.entry_k1[e]
    p0 = geo.positions[k0, v]
    if k0 == k1:
        return p0
    p1 = geo.positions[k1, v]
    alpha = (u * float(geo.num_segments) - float(k0)) / float(k1 - k0)
    return p0 + alpha * (p1 - p0)


@wp.func
def cell_corner(a: wp.vec3, b: wp.vec3, c: wp.vec3, i: int, k: int, n: int) -> wp.vec3:
    """The point of triangle (a, b, c) at barycentrics w_b = i / n, w_c = k / n."""
    wb = float(i) / float(n)
    wc = float(k) / float(n)
    return (1.0 - wb - wc) * a + wb * b + wc * c


@wp.func
def carried(geo: Geometry, e: int, v: int, u: float, sharp: int, u_now: float) -> wp.vec3:
    """Vertex v of entry e where a lookup for map time u takes it: along its span's motion
    (extrapolated), or for a sharp instant at u_now its position moved by its velocity (as
    shading.entry_point_velocity gives a static entry's)."""
    if sharp != 0 and geo.has_velocities != 0:
        return geo.positions[geo.entry_k0[e], v] + (u - u_now) * geo.velocities[v]
    return extrapolated(geo, e, v, u)


@wp.func
def light_test(geo: Geometry, sh: Shading, e: int, j: int, cell: int, occ: wp.array3d(dtype=int),
               block: int, sharp: int, u_now: float) -> int:
    """face_test for every map instant a lookup of light j may read, light sample and face, for
    entry e's points in barycentric cell `cell` (cell_of; -1: the whole triangle): FREE when every
    lookup of light j from them reads only empty texels, else the first failing test's answer.
    sharp: the entries are a sharp instant's at shutter time u_now (accumulation), whose lookups
    read the two map instants around u_now (or the light's one map, in its frame at u_now); else
    every map instant, from points anywhere along the entry's span."""
    first = sh.shadow_lights[j, 0]
    num_samples = sh.shadow_lights[j, 1]
    num_faces = sh.shadow_lights[j, 2]
    vi = geo.tri_vertices[geo.entry_tri[e]]
    times = sh.shadow_times
    moving = geo.entry_k0[e] != geo.entry_k1[e]
    if moving and (times == 1 or sharp != 0):
        return OCCUPIED   # one map read at the lookup's own time: the entry anywhere along its span
    first_b = int(0)
    count = times
    if sharp != 0 and times > 1:
        # light_visibility_at's two instants around u_now (the second read only when blending)
        x = wp.clamp(u_now, 0.0, 1.0) * float(times) - 0.5
        first_b = wp.clamp(int(wp.floor(x)), 0, times - 1)
        count = wp.min(first_b + 1, times - 1) - first_b + 1
    for step in range(count):
        b = first_b + step
        axes = wp.mat33()
        origin = wp.vec3()
        u = float(0.0)
        if times > 1:
            axes, origin = instant_frame(sh, j, b)
            u = (float(b) + 0.5) / float(times)
        elif sharp != 0:
            # the one map is read in the light's frame at the lookup's own time
            u = u_now
            axes = light_axes(sh, j, u)
            origin = light_vec(sh, j, 4, u)
        else:
            # (the caller flags only lights that hold still when there is one map instant)
            axes = light_axes(sh, j, 0.0)
            origin = light_vec(sh, j, 4, 0.0)
        pa = axes * (carried(geo, e, vi[0], u, sharp, u_now) - origin)
        pb = axes * (carried(geo, e, vi[1], u, sharp, u_now) - origin)
        pc = axes * (carried(geo, e, vi[2], u, sharp, u_now) - origin)
        qa = pa
        qb = pb
        qc = pc
        qd = pc
        if cell >= 0:
            # cell (i, k): w_b in [i, i+1] / n, w_c in [k, k+1] / n, within the triangle
            i = cell // CELLS
            k = cell % CELLS
            qa = cell_corner(pa, pb, pc, i, k, CELLS)
            qb = cell_corner(pa, pb, pc, i + 1, k, CELLS)
            qc = cell_corner(pa, pb, pc, i, k + 1, CELLS)
            qd = qc
            if i + k + 2 <= CELLS:
                qd = cell_corner(pa, pb, pc, i + 1, k + 1, CELLS)
        for m in range(num_samples):
            for f in range(num_faces):
                t = face_test(sh, first + m * num_faces + f, qa, qb, qc, qd, occ, block)
                if t != FREE:
                    return t
    return FREE


@wp.func
def cell_of(wb: float, wc: float) -> int:
    """The barycentric cell (light_test) holding the point at barycentrics w_b, w_c: i * CELLS + k
    with i, k the cell's steps along w_b and w_c (i + k < CELLS)."""
    n = CELLS
    i = wp.clamp(int(wp.floor(wb * float(n))), 0, n - 1)
    k = wp.clamp(int(wp.floor(wc * float(n))), 0, n - 1)
    if i + k > n - 1:   # on the far edge (w_b + w_c = 1), or past it by rounding
        k = n - 1 - i
    return i * n + k


@wp.kernel(enable_backward=False)
def entry_shadow_free(geo: Geometry, sh: Shading, occ: wp.array3d(dtype=int), block: int, lights: int,
                      sharp: int, u_now: float, out: wp.array(dtype=int)):
    """out[e * NL + j] (entry e = tid, NL lights): bit cell_of(...) set when no shadow of light j
    can fall on the points of entry e in that barycentric cell; lights: the bits of the lights
    that may be tested; sharp, u_now: see light_test. An entry occupied over a wide box is tested
    cell by cell. Outside a sharp instant, entries that carry vertex velocities are never
    flagged."""
    e = wp.tid()
    nl = sh.num_lights
    for j in range(nl):
        bits = int(0)
        if (sharp != 0 or geo.has_velocities == 0) and j < 31 and ((lights >> j) & 1) != 0:
            t = light_test(geo, sh, e, j, -1, occ, block, sharp, u_now)
            if t == FREE:
                bits = ALL_CELLS
            elif t == OCCUPIED_WIDE:
                for i in range(CELLS):
                    for k in range(CELLS - i):
                        if light_test(geo, sh, e, j, i * CELLS + k, occ, block, sharp, u_now) == FREE:
                            bits = bits | (1 << (i * CELLS + k))
        out[e * nl + j] = bits
