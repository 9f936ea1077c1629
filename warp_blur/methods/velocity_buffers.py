"""The velocity method's per-pixel buffers as Warp kernels over pixel bands (every core): camera
motion from depth, soft-edge velocity and the tile / neighbour maxima the gather reads.

They were NumPy in float64 on one core: 40% of a demo frame at 640×480 (66 of 155 ms), 23% of
`large`'s at 1024×768. Each kernel does per pixel what the NumPy did per array, in float32 (the
camera's relative motion is composed in float64 on the host first); tests/test_velocity_buffers.py
keeps the NumPy forms as the oracle.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ..core import warp_setup  # noqa: F401  (Warp's settings, before anything starts it)
from ..core.camera import Projection
from ..core.parallel import launch_pixels

#: a velocity shorter than this (pixels) is "not moving" for the soft edges' mask and pass-through
STILL_PX = wp.constant(1.0e-3)


@wp.func
def finite(x: float) -> bool:
    """x is neither inf nor nan (a comparison, where wp.isfinite calls a double-precision
    function out of line)."""
    return wp.abs(x) <= 3.4028234663852886e38


@wp.func
def raster_of(x: float, y: float, z: float, window: wp.vec4, width: float, height: float, ortho: int):
    """(x, y, ok) raster position in pixels (x right, y down) of camera-space point (x, y, z); ok
    = 0.0 where the point is not in front of the eye (a perspective view: it has no place on
    screen, as kernels/raster.to_raster says of object motion) or the position is not finite.
    Scalars in and out: vectors assembled a component at a time stall the CPU's stores."""
    wx = x
    wy = y
    if ortho == 0:
        depth = -z
        if depth <= 0.0:
            return 0.0, 0.0, 0.0
        wx = x / depth
        wy = y / depth
    rx = (wx - window[0]) / (window[2] - window[0]) * width
    ry = (window[3] - wy) / (window[3] - window[1]) * height
    if finite(rx) and finite(ry):
        return rx, ry, 1.0
    return 0.0, 0.0, 0.0


@wp.kernel(enable_backward=False)
def add_camera_motion(depth: wp.array(dtype=float), width: int, height: int, window: wp.vec4, ortho: int,
                      open_from_center: wp.mat44, close_from_center: wp.mat44, half_seen: int, both: int,
                      first: int,
                      # in and out
                      motion: wp.array(dtype=wp.vec2), seen_motion: wp.array(dtype=wp.vec2)):
    """motion[pix] += the screen motion (pixels, open -> close) of the static point seen at
    depth[pix] (view depth; inf where nothing is hit), from the camera's motion alone: unprojected
    with the centre camera, reprojected with the open and close cameras (row vectors: p @ M). Where
    nothing is hit, the pixel's ray direction (the dome turns with the camera; nothing in an
    orthographic view or where the turn reaches 90°). A point behind the eye at open or close adds
    nothing, or with half_seen (the velocity method's blur) twice its motion over the half of the
    shutter it is seen in (at the centre it is where the pixel is). both = 1: motion gets the first
    rule and seen_motion the half_seen one, from one projection of the point."""
    pix = first + wp.tid()
    wf = float(width)
    hf = float(height)
    px = float(pix % width) + 0.5
    py = float(pix // width) + 0.5
    wx = window[0] + (px / wf) * (window[2] - window[0])
    wy = window[3] - (py / hf) * (window[3] - window[1])
    z = depth[pix]
    far = not finite(z)
    # the centre camera's point (x, y, zc, w) as scalars (built as vectors a component at a time,
    # it stalled the stores: 44 ns a pixel)
    x = wx * z
    y = wy * z
    zc = -z
    w = float(1.0)
    if far:
        if ortho != 0:
            return
        x = wx
        y = wy
        zc = -1.0
        w = 0.0
    elif ortho != 0:
        x = wx
        y = wy
    m0 = open_from_center
    m1 = close_from_center
    a0 = x * m0[0, 0] + y * m0[1, 0] + zc * m0[2, 0] + w * m0[3, 0]
    a1 = x * m0[0, 1] + y * m0[1, 1] + zc * m0[2, 1] + w * m0[3, 1]
    a2 = x * m0[0, 2] + y * m0[1, 2] + zc * m0[2, 2] + w * m0[3, 2]
    b0 = x * m1[0, 0] + y * m1[1, 0] + zc * m1[2, 0] + w * m1[3, 0]
    b1 = x * m1[0, 1] + y * m1[1, 1] + zc * m1[2, 1] + w * m1[3, 1]
    b2 = x * m1[0, 2] + y * m1[1, 2] + zc * m1[2, 2] + w * m1[3, 2]
    if far and (a2 >= 0.0 or b2 >= 0.0):
        return
    rax, ray, oka = raster_of(a0, a1, a2, window, wf, hf, ortho)
    rbx, rby, okb = raster_of(b0, b1, b2, window, wf, hf, ortho)
    mx = rbx - rax
    my = rby - ray
    if oka == 0.0 and okb == 0.0:
        return
    if oka == 0.0 or okb == 0.0:
        # seen at one end only: no motion AOV; the blur's is twice that of the half it is seen in
        if far or (half_seen == 0 and both == 0):
            return
        if oka != 0.0:
            mx = 2.0 * (px - rax)
            my = 2.0 * (py - ray)
        else:
            mx = 2.0 * (rbx - px)
            my = 2.0 * (rby - py)
        if finite(mx) and finite(my):
            if both != 0:
                seen_motion[pix] = seen_motion[pix] + wp.vec2(mx, my)
            else:
                motion[pix] = motion[pix] + wp.vec2(mx, my)
        return
    if finite(mx) and finite(my):
        motion[pix] = motion[pix] + wp.vec2(mx, my)
        if both != 0:
            seen_motion[pix] = seen_motion[pix] + wp.vec2(mx, my)


@wp.kernel(enable_backward=False)
def half_res_masked(v: wp.array(dtype=wp.vec2), width: int, height: int, half_w: int, first: int,
                    # output
                    low: wp.array(dtype=wp.vec3)):
    """low[k] = (v·mask, mask) of half-resolution pixel k: v the mean of its 2×2 full-resolution
    pixels (zeros past the image's edge count in the mean), mask 1 where |v| > STILL_PX."""
    k = first + wp.tid()
    x = 2 * (k % half_w)
    y = 2 * (k // half_w)
    s = wp.vec2(0.0, 0.0)
    for dy in range(2):
        for dx in range(2):
            if x + dx < width and y + dy < height:
                s = s + v[(y + dy) * width + x + dx]
    s = s * 0.25
    if wp.length(s) > STILL_PX:
        low[k] = wp.vec3(s[0], s[1], 1.0)
    else:
        low[k] = wp.vec3(0.0, 0.0, 0.0)


@wp.kernel(enable_backward=False)
def box_mean(src: wp.array(dtype=wp.vec3), width: int, height: int, r: int, along_x: int, first: int,
             # output
             dst: wp.array(dtype=wp.vec3)):
    """dst[k] = the mean of src over the (2r+1)-wide window about pixel k along x (along_x = 1) or
    y, zeros beyond the edges (a box convolution, mode "same")."""
    k = first + wp.tid()
    x = k % width
    y = k // width
    s = wp.vec3(0.0, 0.0, 0.0)
    if along_x != 0:
        for i in range(wp.max(x - r, 0), wp.min(x + r + 1, width)):
            s = s + src[y * width + i]
    else:
        for j in range(wp.max(y - r, 0), wp.min(y + r + 1, height)):
            s = s + src[j * width + x]
    dst[k] = s / float(2 * r + 1)


@wp.kernel(enable_backward=False)
def soft_half_velocity(v: wp.array(dtype=wp.vec2), blurred: wp.array(dtype=wp.vec3), width: int, half_w: int,
                       scale: float, first: int,
                       # output
                       vhalf: wp.array(dtype=wp.vec2)):
    """vhalf[pix] = scale × (the pixel's own velocity where it moves, else the soft-edge velocity
    of its half-resolution pixel: blurred (v·mask, mask) with the mask divided out)."""
    pix = first + wp.tid()
    own = v[pix]
    out = own
    if not (wp.length(own) > STILL_PX):
        b = blurred[((pix // width) // 2) * half_w + (pix % width) // 2]
        out = wp.vec2(0.0, 0.0)
        if b[2] > 1.0e-6:
            out = wp.vec2(b[0], b[1]) / b[2]
    vhalf[pix] = out * scale


@wp.kernel(enable_backward=False)
def scale_velocity(v: wp.array(dtype=wp.vec2), scale: float, first: int,
                   # output
                   vhalf: wp.array(dtype=wp.vec2)):
    """vhalf[pix] = scale × v[pix] (no soft edges)."""
    pix = first + wp.tid()
    vhalf[pix] = v[pix] * scale


@wp.kernel(enable_backward=False)
def tile_max(vhalf: wp.array(dtype=wp.vec2), width: int, height: int, tile: int, tiles_x: int, first: int,
             # output
             tmax: wp.array(dtype=wp.vec2)):
    """tmax[t] = the longest velocity in tile t (the first in row-major order among equals;
    zero for a tile that holds none, as pixels past the image's edge count as zero)."""
    t = first + wp.tid()
    x0 = (t % tiles_x) * tile
    y0 = (t // tiles_x) * tile
    best = wp.vec2(0.0, 0.0)
    best_len = float(0.0)
    for y in range(y0, wp.min(y0 + tile, height)):
        for x in range(x0, wp.min(x0 + tile, width)):
            c = vhalf[y * width + x]
            n = wp.length(c)
            if n > best_len:
                best = c
                best_len = n
    tmax[t] = best


@wp.kernel(enable_backward=False)
def neighbour_max(tmax: wp.array(dtype=wp.vec2), tiles_x: int, tiles_y: int, first: int,
                  # output
                  nmax: wp.array(dtype=wp.vec2)):
    """nmax[t] = the longest of the tile maxima in the 3×3 tiles about tile t (the first in
    row-major order among equals; tiles past the edge count as zero)."""
    t = first + wp.tid()
    tx = t % tiles_x
    ty = t // tiles_x
    best = wp.vec2(0.0, 0.0)
    best_len = float(0.0)
    for dy in range(-1, 2):
        for dx in range(-1, 2):
            x = tx + dx
            y = ty + dy
            if x >= 0 and x < tiles_x and y >= 0 and y < tiles_y:
                c = tmax[y * tiles_x + x]
                n = wp.length(c)
                if n > best_len:
                    best = c
                    best_len = n
    nmax[t] = best


def camera_motion(depth: wp.array, motion: wp.array, proj: Projection, open_from_center: np.ndarray,
                  close_from_center: np.ndarray, device: str, threads: int | None = None,
                  half_seen: bool = False, seen_motion: wp.array | None = None) -> None:
    """Add to motion ((H*W,) vec2, pixels over the shutter) the camera's motion reconstructed from
    depth ((H*W,) view depth, inf where nothing is hit); the matrices (4, 4 float64, row vectors)
    take centre-camera points to the open and close cameras. half_seen: add_camera_motion's. With
    seen_motion (like motion), the same pass adds to it the half_seen form (the velocity method's
    blur beside its motion AOV: one projection of each pixel for both)."""
    w, h = proj.width, proj.height
    window = wp.vec4(*(float(c) for c in proj.window))
    m0 = wp.mat44(*np.asarray(open_from_center, np.float64).ravel().astype(np.float32))
    m1 = wp.mat44(*np.asarray(close_from_center, np.float64).ravel().astype(np.float32))
    both = int(seen_motion is not None)
    second = seen_motion if seen_motion is not None else motion
    launch_pixels(add_camera_motion, w * h,
                  lambda first, _n: [depth, w, h, window, int(proj.orthographic), m0, m1, int(half_seen), both,
                                     first, motion, second],
                  device, threads)


def soft_half_velocities(v: wp.array, width: int, height: int, radius: float, device: str,
                         threads: int | None = None) -> wp.array:
    """(H*W,) vec2: half of each pixel's velocity, spread past silhouettes (soft edges, radius in
    pixels; 0 = none): a half-resolution (v·mask, mask) box-blurred by radius/2 there (at least 1)
    and divided by the blurred mask stands in where the pixel itself does not move."""
    out = wp.empty(width * height, dtype=wp.vec2, device=device)
    if radius <= 0:
        launch_pixels(scale_velocity, width * height, lambda first, _n: [v, 0.5, first, out], device, threads)
        return out
    hw, hh = (width + 1) // 2, (height + 1) // 2
    r = max(1, int(round(radius / 2)))
    low = wp.empty(hw * hh, dtype=wp.vec3, device=device)
    rows = wp.empty_like(low)
    launch_pixels(half_res_masked, hw * hh, lambda first, _n: [v, width, height, hw, first, low], device, threads)
    launch_pixels(box_mean, hw * hh, lambda first, _n: [low, hw, hh, r, 1, first, rows], device, threads)
    launch_pixels(box_mean, hw * hh, lambda first, _n: [rows, hw, hh, r, 0, first, low], device, threads)
    launch_pixels(soft_half_velocity, width * height, lambda first, _n: [v, low, width, hw, 0.5, first, out],
                  device, threads)
    return out


def tile_maxima(vhalf: wp.array, width: int, height: int, tile: int, device: str,
                threads: int | None = None) -> tuple[wp.array, int, int]:
    """(the longest half velocity in each tile of `tile` pixels ((tiles_y*tiles_x,) vec2),
    tiles_x, tiles_y)."""
    tx, ty = (width + tile - 1) // tile, (height + tile - 1) // tile
    tmax = wp.empty(tx * ty, dtype=wp.vec2, device=device)
    launch_pixels(tile_max, tx * ty, lambda first, _n: [vhalf, width, height, tile, tx, first, tmax], device, threads)
    return tmax, tx, ty


def neighbour_maxima(tmax: wp.array, tiles_x: int, tiles_y: int, device: str,
                     threads: int | None = None) -> wp.array:
    """((tiles_y*tiles_x,) vec2) the longest of the tile maxima tmax in each tile's 3×3 block."""
    nmax = wp.empty_like(tmax)
    launch_pixels(neighbour_max, tiles_x * tiles_y, lambda first, _n: [tmax, tiles_x, tiles_y, first, nmax],
                  device, threads)
    return nmax
