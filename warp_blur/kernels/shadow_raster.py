"""Shadow-map kernels: rendering a face from the light (the sharp rasterizer's visibility, seen
from the light) and warping a key face to another instant or light position through a mesh of
control points (gather per texel over the warped triangles binned to its tile).
"""

from __future__ import annotations

import warp as wp

from .cutout import cutout_hides
from .kernel_types import Bins, Geometry, View
from .raster import centre_ray, nearest_at_centre, to_raster
from .rays import edge_cross, entry_vertex, hit_through_edges, intersect_triangle


@wp.kernel(enable_backward=False)
def render_shadow_texels(view: View, geo: Geometry, bins: Bins, first_pixel: int,
                         # outputs
                         depth: wp.array(dtype=float), tri: wp.array(dtype=int), bary: wp.array(dtype=wp.vec2)):
    """Per texel of a face (geometry already in face space, static entries): the nearest depth
    along the face's view axis (inf where nothing is), the triangle seen and its barycentrics of
    vertices b and c (the warp's control points follow that surface point)."""
    pix = first_pixel + wp.tid()
    o, d = centre_ray(view, pix)
    e, _alpha, hit = nearest_at_centre(view, geo, bins, pix, o, d, 0.0)
    if e < 0:
        depth[pix] = wp.inf
        tri[pix] = -1
        bary[pix] = wp.vec2(0.0, 0.0)
    else:
        depth[pix] = hit[1]
        tri[pix] = geo.entry_tri[e]
        bary[pix] = wp.vec2(hit[2], hit[3])


@wp.func
def within(p: wp.vec3, limit: float) -> bool:
    """True when raster point p's x and y are finite and within +-limit."""
    return wp.abs(p[0]) < limit and wp.abs(p[1]) < limit


@wp.func
def row_span(a: wp.vec3, b: wp.vec3, c: wp.vec3, y: float) -> wp.vec2:
    """(x min, x max) of triangle abc (raster x, y) on the line at height y, widened by a margin
    far above float32 rounding (the exact hit test decides each texel); (1, 0) when the line
    misses the triangle."""
    lo = float(wp.inf)
    hi = float(-wp.inf)
    for k in range(3):
        p = a
        q = b
        if k == 1:
            p = b
            q = c
        elif k == 2:
            p = c
            q = a
        if (p[1] - y) * (q[1] - y) <= 0.0:
            if p[1] == q[1]:
                lo = wp.min(lo, wp.min(p[0], q[0]))
                hi = wp.max(hi, wp.max(p[0], q[0]))
            else:
                x = p[0] + (y - p[1]) * (q[0] - p[0]) / (q[1] - p[1])
                lo = wp.min(lo, x)
                hi = wp.max(hi, x)
    if lo > hi:
        return wp.vec2(1.0, 0.0)
    margin = 1.0e-2 + 1.0e-5 * wp.max(wp.max(wp.abs(lo), wp.abs(hi)), wp.abs(y))
    return wp.vec2(lo - margin, hi + margin)


@wp.func
def grow_box(box: wp.vec4, r: wp.vec3) -> wp.vec4:
    """box (x0, y0, x1, y1) grown to hold raster point r (x, y)."""
    return wp.vec4(wp.min(box[0], r[0]), wp.min(box[1], r[1]), wp.max(box[2], r[0]), wp.max(box[3], r[1]))


@wp.func
def near_crossing(view: View, p: wp.vec3, q: wp.vec3) -> wp.vec3:
    """Raster point where segment pq crosses the near plane (its depth set to the plane's exactly)."""
    dp = -p[2] - view.near
    dq = -q[2] - view.near
    x = p + (dp / (dp - dq)) * (q - p)
    return to_raster(view, wp.vec3(x[0], x[1], -view.near))


@wp.func
def clipped_box(view: View, a: wp.vec3, b: wp.vec3, c: wp.vec3, margin: float) -> wp.vec4:
    """Raster box (x0, y0, x1, y1) of triangle abc's part in front of the near plane (all of it
    when orthographic), widened by margin: the box binning.entry_pixel_bounds gives a still
    triangle on the host, here per launch instead of per map on the host. Empty (x0 > x1) when no
    part is in front or all of it lies beyond the far plane."""
    empty = wp.vec4(1.0, 1.0, 0.0, 0.0)
    za = -a[2]
    zb = -b[2]
    zc = -c[2]
    if view.ortho == 0:
        if za > view.far and zb > view.far and zc > view.far:
            return empty
    box = wp.vec4(wp.inf, wp.inf, -wp.inf, -wp.inf)
    if view.ortho != 0 or (za >= view.near and zb >= view.near and zc >= view.near):
        box = grow_box(grow_box(grow_box(box, to_raster(view, a)), to_raster(view, b)), to_raster(view, c))
    else:
        if za >= view.near:
            box = grow_box(box, to_raster(view, a))
        if zb >= view.near:
            box = grow_box(box, to_raster(view, b))
        if zc >= view.near:
            box = grow_box(box, to_raster(view, c))
        if (za - view.near) * (zb - view.near) < 0.0:
            box = grow_box(box, near_crossing(view, a, b))
        if (zb - view.near) * (zc - view.near) < 0.0:
            box = grow_box(box, near_crossing(view, b, c))
        if (zc - view.near) * (za - view.near) < 0.0:
            box = grow_box(box, near_crossing(view, c, a))
    if not (box[0] <= box[2] and box[1] <= box[3]):
        return empty
    return wp.vec4(box[0] - margin, box[1] - margin, box[2] + margin, box[3] + margin)


@wp.kernel(enable_backward=False)
def splat_boxes(view: View, geo: Geometry, cull: wp.array(dtype=float), num_tris: int, first: int,
                # output
                boxes: wp.array(dtype=wp.vec4i)):
    """boxes[e] for entry e = first + tid (static, in face space, at instant entry_k0): the texel
    box (x0, y0, x1, y1), inclusive, whose centres its hit test may pass in splat_shadow_depth,
    clamped to the face; x0 > x1 when it can hold no depth there (outside the face or the clipping
    range, or a back face of a closed instance that the light is outside: cull, when not empty,
    at instant k and triangle t [k * num_tris + t] is that instance's sign, 0 to keep; see
    shadows/direct.py, FaceRasterizer.cull_signs). Found once per entry rather than once per row
    band: over many small triangles the set-up, not the texels, is a splat's cost."""
    e = first + wp.tid()
    empty = wp.vec4i(1, 1, 0, 0)
    vi = geo.tri_vertices[geo.entry_tri[e]]
    a = entry_vertex(geo, e, vi[0], 0.0)
    b = entry_vertex(geo, e, vi[1], 0.0)
    c = entry_vertex(geo, e, vi[2], 0.0)
    if cull.shape[0] > 0:
        sign = cull[geo.entry_k0[e] * num_tris + geo.entry_tri[e]]
        if sign != 0.0:
            # facing seen from the light: det(a, b, c) with the light at the origin, -n_z from +z
            facing = float(0.0)
            if view.ortho != 0:
                facing = -wp.cross(b - a, c - a)[2]
            else:
                facing = wp.dot(a, wp.cross(b, c))
            if facing * sign > 0.0:
                boxes[e] = empty
                return
    box = clipped_box(view, a, b, c, 1.0)
    if not (box[0] <= box[2]):
        boxes[e] = empty
        return
    # clamped before the conversion to int (a vertex just in front of the eye projects far out)
    limit = float(4 * (view.width + view.height))
    x0 = wp.max(int(wp.ceil(wp.clamp(box[0], -limit, limit) - 0.5)), 0)
    x1 = wp.min(int(wp.floor(wp.clamp(box[2], -limit, limit) - 0.5)), view.width - 1)
    y0 = wp.max(int(wp.ceil(wp.clamp(box[1], -limit, limit) - 0.5)), 0)
    y1 = wp.min(int(wp.floor(wp.clamp(box[3], -limit, limit) - 0.5)), view.height - 1)
    if x0 > x1 or y0 > y1:
        boxes[e] = empty
        return
    boxes[e] = wp.vec4i(x0, y0, x1, y1)


@wp.kernel(enable_backward=False)
def splat_shadow_depth(view: View, geo: Geometry, boxes: wp.array(dtype=wp.vec4i), row_lo: int, row_hi: int,
                       stride: int, block: int,
                       # in/out
                       depth: wp.array(dtype=float), touched: wp.array(dtype=wp.uint8),
                       occupied: wp.array(dtype=wp.uint8)):
    """depth[texel * stride + k] = min(that, entry's depth there) for entry tid (static, in face
    space, at instant k = its entry_k0) over the texel centres of its box (splat_boxes) within
    rows [row_lo, row_hi) (the pairs the texel walk of render_shadow_texels tests, with the same
    hit test): few, small triangles over a base map cost their own area, not the map's. stride 1
    with k 0 is one map; stride B renders B instants of a face at once, each texel's instants side
    by side (the layout lookups read); touched (when not empty) gets 1 at every texel an entry
    covers (over a face filled with the same base at every instant, texels never touched are the
    same at every instant); occupied (when not empty, (ceil(S / block)²,)) gets 1 at every
    block × block texel block where an entry writes a depth (the occupancy shadows/free_entries.py
    tests, found here rather than by reading the maps again). The box is found on the device
    (splat_boxes), so a face costs the host no binning.
    Launches for disjoint row bands may run in parallel: an entry outside a band's rows costs
    that band a read of its box."""
    e = wp.tid()
    box = boxes[e]
    y0 = wp.max(box[1], row_lo)
    y1 = wp.min(box[3], row_hi - 1)
    if box[0] > box[2] or y0 > y1:
        return
    x0 = box[0]
    x1 = box[2]
    vi = geo.tri_vertices[geo.entry_tri[e]]
    a = entry_vertex(geo, e, vi[0], 0.0)
    b = entry_vertex(geo, e, vi[1], 0.0)
    c = entry_vertex(geo, e, vi[2], 0.0)
    blocks_x = (view.width + block - 1) // block   # occupied's row length
    # a perspective face's rays all start at the eye (the origin): the edges' cross products
    # are the triangle's own, computed once (the same values intersect_triangle computes)
    c_ab = edge_cross(a, b, vi[0], vi[1])
    c_bc = edge_cross(b, c, vi[1], vi[2])
    c_ca = edge_cross(c, a, vi[2], vi[0])
    # the triangle in raster space (all vertices in front of the eye: its edges project to
    # straight lines), so each row tests only the texels near its span, not the whole box
    ra = to_raster(view, a)
    rb = to_raster(view, b)
    rc = to_raster(view, c)
    spans = ra[2] > 0.0 and rb[2] > 0.0 and rc[2] > 0.0 and within(ra, 1.0e7) and within(rb, 1.0e7) \
        and within(rc, 1.0e7)
    for py in range(y0, y1 + 1):
        lo = x0
        hi = x1
        if spans:
            xr = row_span(ra, rb, rc, float(py) + 0.5)
            lo = wp.max(x0, int(wp.ceil(xr[0] - 0.5)))
            hi = wp.min(x1, int(wp.floor(xr[1] - 0.5)))
        for px in range(lo, hi + 1):
            o, d = centre_ray(view, py * view.width + px)
            hit = wp.vec4(0.0)
            if view.ortho == 0:
                hit = hit_through_edges(d, a, b, c, c_ab, c_bc, c_ca)
            else:
                hit = intersect_triangle(o, d, a, b, c, vi)
            if hit[0] > 0.0 and hit[1] >= view.near and hit[1] <= view.far:
                if not cutout_hides(geo, geo.entry_tri[e], hit[2], hit[3], 0.0, float(px) + 0.5,
                                    float(py) + 0.5):
                    wp.atomic_min(depth, (py * view.width + px) * stride + geo.entry_k0[e], hit[1])
                    if touched.shape[0] > 0:
                        touched[py * view.width + px] = wp.uint8(1)
                    if occupied.shape[0] > 0:
                        # (row bands share a block row at their edges: both write 1)
                        occupied[(py // block) * blocks_x + px // block] = wp.uint8(1)


@wp.kernel(enable_backward=False)
def flag_varying_texels(depth: wp.array(dtype=float), size: int, times: int,
                        # output
                        varying: wp.array(dtype=wp.uint8)):
    """Row tid of a texel-major face: varying[texel] = 1 when the texel's `times` depths are not
    all equal (layout.face_varying's flags), else 0. A row per thread."""
    y = wp.tid()
    for x in range(size):
        t = y * size + x
        d0 = depth[t * times]
        flag = wp.uint8(0)
        for b in range(1, times):
            if depth[t * times + b] != d0:
                flag = wp.uint8(1)
        varying[t] = flag


@wp.kernel(enable_backward=False)
def warp_texels(size: int, tiles_x: int, tile_size: int, key_depth: wp.array3d(dtype=float),
                prim_src: wp.array(dtype=wp.vec2), prim_dst: wp.array(dtype=wp.vec2),
                prim_dz: wp.array(dtype=wp.vec3), prim_key: wp.array(dtype=int),
                tile_offsets: wp.array(dtype=int), tile_prims: wp.array(dtype=int), first_pixel: int,
                # outputs
                depth: wp.array(dtype=float)):
    """depth[texel] = min(depth[texel], the nearest over the warped triangles covering the texel
    centre of (key depth at the back-mapped source texel + the interpolated depth change)); start
    from inf: a texel where no triangle lands stays inf (nothing known to cast a shadow there).

    Triangle i has source positions prim_src[3i..3i+2] (texels of key face prim_key[i]), target
    positions prim_dst[3i..3i+2] (texels of the target face) and depth changes prim_dz[i]."""
    pix = first_pixel + wp.tid()
    px = pix % size
    py = pix // size
    x = float(px) + 0.5
    y = float(py) + 0.5
    tile = (py // tile_size) * tiles_x + px // tile_size
    best = depth[pix]   # min with what other keys already put here
    for k in range(tile_offsets[tile], tile_offsets[tile + 1]):
        i = tile_prims[k]
        a = prim_dst[3 * i]
        b = prim_dst[3 * i + 1]
        c = prim_dst[3 * i + 2]
        den = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
        if den != 0.0:
            wb = ((x - a[0]) * (c[1] - a[1]) - (y - a[1]) * (c[0] - a[0])) / den
            wc = ((b[0] - a[0]) * (y - a[1]) - (b[1] - a[1]) * (x - a[0])) / den
            wa = 1.0 - wb - wc
            tol = -1.0e-5
            if wa >= tol and wb >= tol and wc >= tol:
                src = wa * prim_src[3 * i] + wb * prim_src[3 * i + 1] + wc * prim_src[3 * i + 2]
                sx = wp.clamp(int(wp.floor(src[0])), 0, size - 1)
                sy = wp.clamp(int(wp.floor(src[1])), 0, size - 1)
                dz = prim_dz[i]
                z = key_depth[prim_key[i], sy, sx] + wa * dz[0] + wb * dz[1] + wc * dz[2]
                if z < best:
                    best = z
    depth[pix] = best
