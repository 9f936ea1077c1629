"""The one sharp rasterizer: nearest hit per pixel sample at a shutter time, shaded, accumulated.

Accumulation calls it once per instant; the velocity method and the Z/motion AOVs use its
visibility at the shutter centre. Work is pixel-parallel over row bands (see parallel.py); each
pixel walks the entries binned to its tile.
"""

from __future__ import annotations

import warp as wp

from .cutout import cutout_hides
from .dome import dome_at
from .kernel_types import Bins, Geometry, Shading, View
from .rays import entry_alpha, entry_vertex, intersect_triangle, pixel_ray_direction, pixel_ray_origin
from .shading import shade_entry_hit, shadows_steady_at


@wp.func
def pixel_tile(view: View, px: int, py: int) -> int:
    return (py // view.tile_size) * view.tiles_x + px // view.tile_size


@wp.func
def listed_pixel(view: View, pixels: wp.array(dtype=int), k: int):
    """(flat index, x, y, screen tile) of listed pixel pixels[k]."""
    pix = pixels[k]
    px = pix % view.width
    py = pix // view.width
    return pix, px, py, pixel_tile(view, px, py)


@wp.func
def box_rejects(bins: Bins, e: int, x: float, y: float) -> bool:
    """True when the sample (x, y pixels) lies outside entry e's swept pixel box or one of its
    swept slabs (binning.swept_bands)."""
    b = bins.entry_boxes[e]
    if x < b[0] or x > b[2] or y < b[1] or y > b[3]:
        return True
    for k in range(bins.entry_bands.shape[1]):
        n = bins.entry_bands[e, k]
        w = n[0] * x + n[1] * y
        if w < n[2] or w > n[3]:
            return True
    return False


#: how far (relative) an entry's nearest vertex must lie beyond a hit for a list walk to stop
#: there: room for the float32 rounding of hit depths (~1e-7 relative) and of the stored bound
NEAR_STOP_MARGIN = wp.constant(1.0e-5)


@wp.func
def list_beyond(bins: Bins, e: int, z: float) -> bool:
    """True when entry e, and so every entry after it in a list running nearest first
    (bins.entry_near), lies wholly beyond depth z: none can be hit nearer than z."""
    return bins.entry_near[e] > z + NEAR_STOP_MARGIN * wp.abs(z) + 1.0e-30


@wp.func
def nearest_entry(view: View, geo: Geometry, bins: Bins, tile: int, sx: float, sy: float, o: wp.vec3, d: wp.vec3,
                  u: float):
    """Nearest entry hit by the ray of sample (sx, sy) at shutter time u within the clipping range.

    Returns (entry or -1, interpolation alpha, hit (1, depth, w_b, w_c)). Ties in depth go to the
    lower entry index, so the result is deterministic. Cut-out points are passed through (cutout.py).
    Where the tile lists run nearest first (bins.entry_near), the walk stops at the first entry
    whose nearest depth is beyond the hit found (list_beyond).
    """
    best_e = int(-1)
    best_alpha = float(0.0)
    best = wp.vec4(0.0, 0.0, 0.0, 0.0)
    sorted_lists = bins.near_sorted != 0
    for i in range(bins.tile_offsets[tile], bins.tile_offsets[tile + 1]):
        e = bins.tile_entries[i]
        if sorted_lists and best_e >= 0 and list_beyond(bins, e, best[1]):
            break
        alpha = entry_alpha(geo, e, u)
        if alpha >= 0.0 and not box_rejects(bins, e, sx, sy):
            vi = geo.tri_vertices[geo.entry_tri[e]]
            hit = intersect_triangle(o, d, entry_vertex(geo, e, vi[0], alpha), entry_vertex(geo, e, vi[1], alpha),
                                     entry_vertex(geo, e, vi[2], alpha), vi)
            if hit[0] > 0.0 and hit[1] >= view.near and hit[1] <= view.far:
                nearer = best_e < 0 or hit[1] < best[1] or (hit[1] == best[1] and e < best_e)
                if nearer and not cutout_hides(geo, geo.entry_tri[e], hit[2], hit[3], u, sx, sy):
                    best_e = e
                    best_alpha = alpha
                    best = hit
    return best_e, best_alpha, best


@wp.func
def centre_ray(view: View, pix: int):
    """(origin, direction) of the ray through pixel pix's centre (camera space)."""
    x = float(pix % view.width) + 0.5
    y = float(pix // view.width) + 0.5
    return pixel_ray_origin(view, x, y), pixel_ray_direction(view, x, y)


@wp.func
def nearest_at_centre(view: View, geo: Geometry, bins: Bins, pix: int, o: wp.vec3, d: wp.vec3, u: float):
    """nearest_entry for the centre ray (o, d) of pixel pix, from its tile's entries."""
    px = pix % view.width
    py = pix // view.width
    return nearest_entry(view, geo, bins, pixel_tile(view, px, py), float(px) + 0.5, float(py) + 0.5, o, d, u)


@wp.func
def to_raster(view: View, p: wp.vec3) -> wp.vec3:
    """Camera-space point -> (raster x, raster y, 1), or (0, 0, 0) when it is not in front of the eye."""
    wx = p[0]
    wy = p[1]
    if view.ortho == 0:
        z = -p[2]
        if z <= 0.0:
            return wp.vec3(0.0, 0.0, 0.0)
        wx = wx / z
        wy = wy / z
    rx = (wx - view.win_min[0]) / (view.win_max[0] - view.win_min[0]) * float(view.width)
    ry = (view.win_max[1] - wy) / (view.win_max[1] - view.win_min[1]) * float(view.height)
    return wp.vec3(rx, ry, 1.0)


# inlined: the body of every sharp pass's sub-sample loop
@wp.func(inline=True)
def subsample_nearest(view: View, geo: Geometry, bins: Bins, tile: int, px: int, py: int, sx: int, sy: int,
                      u: float):
    """(ray origin, direction, nearest_entry's (entry, alpha, hit)) of sub-sample (sx, sy) of the
    view's n×n grid in pixel (px, py) (tile: the pixel's), at shutter time u."""
    n = view.spatial
    x = float(px) + (float(sx) + 0.5) / float(n)
    y = float(py) + (float(sy) + 0.5) / float(n)
    o = pixel_ray_origin(view, x, y)
    d = pixel_ray_direction(view, x, y)
    e, alpha, hit = nearest_entry(view, geo, bins, tile, x, y, o, d, u)
    return o, d, e, alpha, hit


@wp.func
def sharp_pixel(view: View, geo: Geometry, sh: Shading, bins: Bins, u: float, weight: float, pix: int,
                rgba: wp.array2d(dtype=float), record: int, row: int, rec_e: wp.array2d(dtype=int),
                rec_hit: wp.array2d(dtype=wp.vec4), done: wp.array(dtype=wp.uint8)):
    """rgba[pix] += weight × pixel pix of the sharp image at shutter time u (n×n sub-samples);
    with record >= 1, each sub-sample's triangle (-1: none) and hit go to rec_e[row, s], rec_hit[row, s].
    record = 2 (still surfaces under lights that hold still, their shadows may not): a pixel whose
    every sub-sample's shadow lookups read only texels that never change (shadows_steady_at)
    looks the same at every instant, so it is added whole (weight 1) and marked done[row] = 1
    for shade_recorded to skip; the others are added with `weight`, as one instant of many."""
    px = pix % view.width
    py = pix // view.width
    tile = pixel_tile(view, px, py)
    n = view.spatial
    color = wp.vec3(0.0, 0.0, 0.0)
    cover = float(0.0)
    steady = int(0)
    if record == 2:
        steady = 1
    for sy in range(n):
        for sx in range(n):
            o, d, e, alpha, hit = subsample_nearest(view, geo, bins, tile, px, py, sx, sy, u)
            if record != 0:
                tri = int(-1)
                if e >= 0:
                    tri = geo.entry_tri[e]
                rec_e[row, sy * n + sx] = tri
                rec_hit[row, sy * n + sx] = hit
            if e >= 0:
                color = color + shade_entry_hit(view, geo, sh, e, alpha, u, o, d, hit)
                cover = cover + 1.0
                if steady != 0 and not shadows_steady_at(view, geo, sh, e, u, o, d, hit):
                    steady = 0
            else:
                color = color + dome_at(sh, d, u)
    w = weight
    if record == 2:
        done[row] = wp.uint8(steady)
        if steady != 0:
            w = 1.0
    add_pixel(rgba, pix, w / float(n * n), color, cover)


@wp.func
def add_pixel(rgba: wp.array2d(dtype=float), pix: int, w: float, color: wp.vec3, cover: float):
    rgba[pix, 0] = rgba[pix, 0] + w * color[0]
    rgba[pix, 1] = rgba[pix, 1] + w * color[1]
    rgba[pix, 2] = rgba[pix, 2] + w * color[2]
    rgba[pix, 3] = rgba[pix, 3] + w * cover


@wp.kernel(enable_backward=False)
def render_sharp(view: View, geo: Geometry, sh: Shading, bins: Bins, u: float, weight: float,
                 pixels: wp.array(dtype=int), listed: int, first: int, record: int,
                 # outputs
                 rgba: wp.array2d(dtype=float), rec_e: wp.array2d(dtype=int), rec_hit: wp.array2d(dtype=wp.vec4),
                 done: wp.array(dtype=wp.uint8)):
    """Add weight × (the sharp image at shutter time u) to rgba (H*W, 4): at pixel first + tid, or
    with listed = 1 at pixels[first + tid] (recording each sub-sample's hit in row first + tid of
    rec_e / rec_hit when record >= 1, for shade_recorded; record = 2 also adds the pixels whose
    shading never changes whole and marks them in done: sharp_pixel)."""
    k = first + wp.tid()
    pix = k
    if listed != 0:
        pix = pixels[k]
    sharp_pixel(view, geo, sh, bins, u, weight, pix, rgba, record, k, rec_e, rec_hit, done)


@wp.kernel(enable_backward=False)
def shade_recorded(view: View, geo: Geometry, sh: Shading, u: float, weight: float, pixels: wp.array(dtype=int),
                   first: int, rec_e: wp.array2d(dtype=int), rec_hit: wp.array2d(dtype=wp.vec4),
                   rows: wp.array(dtype=int), use_rows: int,
                   # outputs
                   rgba: wp.array2d(dtype=float)):
    """render_sharp at listed pixels whose visibility is known not to change (recorded at another
    instant): only the shading at time u (lights, shadows, normals) is redone. Thread t reshades
    listed pixel k = first + t, or with use_rows = 1 pixel k = rows[first + t] (the pixels whose
    shading changes: render_sharp with record = 2 added the others whole). geo's entries are all triangles
    (entry = triangle index), as recorded."""
    k = first + wp.tid()
    if use_rows != 0:
        k = rows[k]
    pix = pixels[k]
    px = pix % view.width
    py = pix // view.width
    n = view.spatial
    color = wp.vec3(0.0, 0.0, 0.0)
    cover = float(0.0)
    for sy in range(n):
        for sx in range(n):
            e = rec_e[k, sy * n + sx]
            if e >= 0:
                x = float(px) + (float(sx) + 0.5) / float(n)
                y = float(py) + (float(sy) + 0.5) / float(n)
                color = color + shade_entry_hit(view, geo, sh, e, 0.0, u, pixel_ray_origin(view, x, y),
                                                pixel_ray_direction(view, x, y), rec_hit[k, sy * n + sx])
                cover = cover + 1.0
            else:
                x = float(px) + (float(sx) + 0.5) / float(n)
                y = float(py) + (float(sy) + 0.5) / float(n)
                color = color + dome_at(sh, pixel_ray_direction(view, x, y), u)
    add_pixel(rgba, pix, weight / float(n * n), color, cover)


@wp.kernel(enable_backward=False)
def record_nearest(view: View, geo: Geometry, sh: Shading, bins: Bins, u: float, pixels: wp.array(dtype=int),
                   first: int, shade: int,
                   # outputs
                   rec_e: wp.array2d(dtype=int), rec_hit: wp.array2d(dtype=wp.vec4),
                   rec_color: wp.array2d(dtype=wp.vec3), rec_kept: wp.array2d(dtype=wp.uint8)):
    """For listed pixel pixels[first + tid] (row first + tid), each sub-sample's nearest entry at
    shutter time u: its triangle (-1: none) and hit; with shade = 1 its radiance then (zero where
    nothing is hit), for every instant; with shade = 2 (still surfaces under still lights whose
    shadows may change) its radiance where its shadow lookups never change (rec_kept 1:
    shadows_steady_at), the others to be shaded per instant. Nothing is added to the image:
    render_over_recorded composites it."""
    k = first + wp.tid()
    pix, px, py, tile = listed_pixel(view, pixels, k)
    n = view.spatial
    for sy in range(n):
        for sx in range(n):
            o, d, e, alpha, hit = subsample_nearest(view, geo, bins, tile, px, py, sx, sy, u)
            tri = int(-1)
            color = wp.vec3(0.0, 0.0, 0.0)
            kept = int(shade)
            if e >= 0:
                tri = geo.entry_tri[e]
                if shade == 2 and not shadows_steady_at(view, geo, sh, e, u, o, d, hit):
                    kept = 0
                if kept != 0:
                    color = shade_entry_hit(view, geo, sh, e, alpha, u, o, d, hit)
            rec_e[k, sy * n + sx] = tri
            rec_hit[k, sy * n + sx] = hit
            if shade != 0:   # (rec_color and rec_kept hold one element otherwise)
                rec_color[k, sy * n + sx] = color
                rec_kept[k, sy * n + sx] = wp.uint8(wp.min(kept, 1))


@wp.kernel(enable_backward=False)
def render_over_recorded(view: View, geo: Geometry, sh: Shading, bins: Bins, u: float, weight: float,
                         pixels: wp.array(dtype=int), first: int, kept: int, rec_e: wp.array2d(dtype=int),
                         rec_hit: wp.array2d(dtype=wp.vec4), rec_color: wp.array2d(dtype=wp.vec3),
                         rec_kept: wp.array2d(dtype=wp.uint8),
                         # outputs
                         rgba: wp.array2d(dtype=float)):
    """render_sharp at listed pixels where a recorded surface (record_nearest over the triangles
    that look the same at every instant) stands behind the triangles that change: only the latter
    are in bins (geo's entries are all triangles, entry = triangle index); each sub-sample shows
    the nearer of the two (equal depths: the lower triangle index, as nearest_entry decides), the
    recorded one with its recorded radiance where kept = 1 and rec_kept says it was kept, else
    shaded at u."""
    k = first + wp.tid()
    pix, px, py, tile = listed_pixel(view, pixels, k)
    n = view.spatial
    color = wp.vec3(0.0, 0.0, 0.0)
    cover = float(0.0)
    for sy in range(n):
        for sx in range(n):
            o, d, e, alpha, hit = subsample_nearest(view, geo, bins, tile, px, py, sx, sy, u)
            r = rec_e[k, sy * n + sx]
            r_hit = rec_hit[k, sy * n + sx]
            if e >= 0 and (r < 0 or hit[1] < r_hit[1] or (hit[1] == r_hit[1] and e < r)):
                color = color + shade_entry_hit(view, geo, sh, e, alpha, u, o, d, hit)
                cover = cover + 1.0
            elif r >= 0:
                if kept != 0 and rec_kept[k, sy * n + sx] != wp.uint8(0):
                    color = color + rec_color[k, sy * n + sx]
                else:
                    color = color + shade_entry_hit(view, geo, sh, r, 0.0, u, o, d, r_hit)
                cover = cover + 1.0
            else:
                color = color + dome_at(sh, d, u)
    add_pixel(rgba, pix, weight / float(n * n), color, cover)


#: radiance slots per sub-sample in render_over_recorded_instants (the changing surfaces a
#: sub-sample shows, most often one translucent layer, or two)
INSTANT_CACHE_SLOTS = wp.constant(2)


@wp.kernel(enable_backward=False)
def render_over_recorded_instants(view: View, geo: Geometry, sh: Shading, bins: Bins, us: wp.array(dtype=float),
                                  weight: float, pixels: wp.array(dtype=int), first: int,
                                  rec_e: wp.array2d(dtype=int), rec_hit: wp.array2d(dtype=wp.vec4),
                                  rec_color: wp.array2d(dtype=wp.vec3),
                                  # scratch (row k: INSTANT_CACHE_SLOTS per sub-sample) and output
                                  cache_e: wp.array2d(dtype=int), cache_color: wp.array2d(dtype=wp.vec3),
                                  rgba: wp.array2d(dtype=float), rgba_odd: wp.array2d(dtype=float)):
    """render_over_recorded at every instant us[i] in turn, in one launch, for a frame where
    nothing moves and shading is steady (lights, shadows and dome the same at every instant) and
    the changing triangles change only in presence (fractional opacity): a sub-sample's hit on a
    triangle is then the same point, with the same radiance, at every instant, so it is shaded once
    and remembered (INSTANT_CACHE_SLOTS per sub-sample; a surface beyond them is shaded again).
    The recorded surface shows its recorded radiance (recorded with shade = 1). Each instant adds
    weight × its colour as render_over_recorded's pass at that instant would, in the same order:
    the even-indexed instants into rgba, the odd into rgba_odd (the accumulation's two half sums;
    the same array as rgba for one sum)."""
    k = first + wp.tid()
    pix, px, py, tile = listed_pixel(view, pixels, k)
    n = view.spatial
    slots = INSTANT_CACHE_SLOTS
    for c in range(n * n * slots):
        cache_e[k, c] = -1
    for i in range(us.shape[0]):
        u = us[i]
        color = wp.vec3(0.0, 0.0, 0.0)
        cover = float(0.0)
        for sy in range(n):
            for sx in range(n):
                s = sy * n + sx
                o, d, e, alpha, hit = subsample_nearest(view, geo, bins, tile, px, py, sx, sy, u)
                r = rec_e[k, s]
                r_hit = rec_hit[k, s]
                if e >= 0 and (r < 0 or hit[1] < r_hit[1] or (hit[1] == r_hit[1] and e < r)):
                    found = int(-1)
                    free = int(-1)
                    for c in range(s * slots, (s + 1) * slots):
                        if cache_e[k, c] == e:
                            found = c
                        elif cache_e[k, c] < 0 and free < 0:
                            free = c
                    if found >= 0:
                        color = color + cache_color[k, found]
                    else:
                        radiance = shade_entry_hit(view, geo, sh, e, alpha, u, o, d, hit)
                        if free >= 0:
                            cache_e[k, free] = e
                            cache_color[k, free] = radiance
                        color = color + radiance
                    cover = cover + 1.0
                elif r >= 0:
                    color = color + rec_color[k, s]
                    cover = cover + 1.0
                else:
                    color = color + dome_at(sh, d, u)
        if i % 2 == 0:
            add_pixel(rgba, pix, weight / float(n * n), color, cover)
        else:
            add_pixel(rgba_odd, pix, weight / float(n * n), color, cover)


@wp.func
def store_depth_motion(view: View, geo: Geometry, e: int, hit: wp.vec4, k_open: int, k_close: int, pix: int,
                       depth: wp.array(dtype=float), motion: wp.array(dtype=wp.vec2),
                       gather: wp.array(dtype=wp.vec2)):
    """Z and screen motion (pixels, knot k_open to k_close) of the point hit on entry e (e < 0:
    nothing seen, Z inf and motion 0). A point behind the eye at one end has no screen motion
    (0, SPEC's motion AOV); where gather holds the pixel (the velocity method's blur), it gets
    twice the motion of the half it is seen in instead (centre at the knot halfway), so what
    passes the camera still blurs. Elsewhere gather holds the motion."""
    if e < 0:
        depth[pix] = wp.inf
        motion[pix] = wp.vec2(0.0, 0.0)
        if gather.shape[0] > pix:
            gather[pix] = wp.vec2(0.0, 0.0)
        return
    depth[pix] = hit[1]
    vi = geo.tri_vertices[geo.entry_tri[e]]
    wb = hit[2]
    wc = hit[3]
    wa = 1.0 - wb - wc
    p0 = wa * geo.positions[k_open, vi[0]] + wb * geo.positions[k_open, vi[1]] + wc * geo.positions[k_open, vi[2]]
    p1 = wa * geo.positions[k_close, vi[0]] + wb * geo.positions[k_close, vi[1]] + wc * geo.positions[k_close, vi[2]]
    r0 = to_raster(view, p0)
    r1 = to_raster(view, p1)
    m = wp.vec2(0.0, 0.0)
    if r0[2] > 0.0 and r1[2] > 0.0:
        m = wp.vec2(r1[0] - r0[0], r1[1] - r0[1])
    motion[pix] = m
    if gather.shape[0] > pix:
        g = m
        if (r0[2] > 0.0) != (r1[2] > 0.0):
            kc = (k_open + k_close) // 2
            pc = wa * geo.positions[kc, vi[0]] + wb * geo.positions[kc, vi[1]] + wc * geo.positions[kc, vi[2]]
            rc = to_raster(view, pc)
            if rc[2] > 0.0:
                if r0[2] > 0.0:
                    g = 2.0 * wp.vec2(rc[0] - r0[0], rc[1] - r0[1])
                else:
                    g = 2.0 * wp.vec2(r1[0] - rc[0], r1[1] - rc[1])
        gather[pix] = g


@wp.kernel(enable_backward=False)
def render_depth_motion(view: View, geo: Geometry, bins: Bins, u: float, k_open: int, k_close: int,
                        first_pixel: int,
                        # outputs
                        depth: wp.array(dtype=float), motion: wp.array(dtype=wp.vec2),
                        gather: wp.array(dtype=wp.vec2)):
    """Z (view depth at shutter time u, inf where nothing is seen) and the screen motion in pixels
    of the seen point from knot k_open to knot k_close (x right, y down; 0 where nothing is seen);
    gather (empty, or one per pixel): the velocity method's blur velocity (store_depth_motion)."""
    pix = first_pixel + wp.tid()
    o, d = centre_ray(view, pix)
    e, _alpha, hit = nearest_at_centre(view, geo, bins, pix, o, d, u)
    store_depth_motion(view, geo, e, hit, k_open, k_close, pix, depth, motion, gather)


@wp.kernel(enable_backward=False)
def render_sharp_depth_motion(view: View, geo: Geometry, sh: Shading, bins: Bins, u: float, k_open: int,
                              k_close: int, first_pixel: int,
                              # outputs
                              rgba: wp.array2d(dtype=float), depth: wp.array(dtype=float),
                              motion: wp.array(dtype=wp.vec2), gather: wp.array(dtype=wp.vec2)):
    """render_sharp (weight 1, pixel centres) and render_depth_motion from one visibility pass:
    the velocity method's sharp image, Z and object motion."""
    pix = first_pixel + wp.tid()
    o, d = centre_ray(view, pix)
    e, alpha, hit = nearest_at_centre(view, geo, bins, pix, o, d, u)
    color = dome_at(sh, d, u)
    cover = float(0.0)
    if e >= 0:
        color = shade_entry_hit(view, geo, sh, e, alpha, u, o, d, hit)
        cover = 1.0
    add_pixel(rgba, pix, 1.0, color, cover)
    store_depth_motion(view, geo, e, hit, k_open, k_close, pix, depth, motion, gather)
