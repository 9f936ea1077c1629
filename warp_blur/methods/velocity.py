"""Velocity-buffer motion blur, the fast tier (SPEC §5): one sharp render at the shutter centre,
a per-pixel velocity buffer, and a depth-aware gather along the velocity.

- Velocity (pixels over the whole shutter, x right, y down) = object motion + camera motion.
  Object motion: each vertex's world position at shutter open and close (USD's own motion,
  deforming and skinned meshes included) seen from the centre camera, interpolated per pixel.
  Camera motion, reconstructed from depth: the pixel is unprojected with the centre camera and
  reprojected with the open and close cameras. No camera work when the camera does not move.
- Soft edges: a half-resolution copy of the velocity with a mask channel (1 where something
  moves) is box-blurred by `soft_edge_radius` and divided by the blurred mask, so velocity spreads
  past silhouettes without losing its length; it stands in where the pixel itself is static.
- Surface-facing weighting: where the surface (normal from the depth buffer) faces along its
  screen motion the velocity is scaled by `front_blur`, against it by `back_blur`.
- Tile max (tiles as large as the largest blur radius) and neighbour max (3×3 tiles) give the
  dominant velocity around each pixel, so blur reaches outside a moving object's silhouette.
- Gather (McGuire et al. 2012 reconstruction): N jittered samples along the neighbour-max
  velocity with Gaussian weights, each weighted by depth-aware cone/cylinder terms so that a
  static background does not smear over a moving foreground and a moving object does not smear
  over what is in front of it.
- Vertex-trail extrusion (option): vertices whose normals face their motion are placed at
  shutter close, the others at open, stretching silhouettes before the gather.
Known limits: blur from shading changes (a moving shadow on a static receiver, a moving light)
cannot appear, since only geometry has velocity; overlapping motions are approximated.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ..raster.binning import tile_mask_pixels
from ..raster.device_data import make_bins, make_geometry
from .frame import FrameContext
from ..core.parallel import launch_pixels
from ..core.affine import invert_affine
from ..kernels.raster import render_depth_motion, render_sharp, render_sharp_depth_motion
from ..usd.normals import vertex_normals

SOFT_Z = wp.constant(0.01)


@wp.func
def cone(dist: float, v_len: float) -> float:
    if v_len <= 1.0e-6:
        return 0.0
    return wp.clamp(1.0 - dist / v_len, 0.0, 1.0)


@wp.func
def cylinder(dist: float, v_len: float) -> float:
    return 1.0 - wp.smoothstep(0.95 * v_len, 1.05 * v_len + 1.0e-6, dist)


@wp.func
def soft_depth_compare(za: float, zb: float) -> float:
    """1 when za is in front of zb (smaller view depth), fading over a relative extent."""
    extent = SOFT_Z * wp.max(wp.min(za, zb), 1.0e-6)
    return wp.clamp(1.0 - (za - zb) / extent, 0.0, 1.0)


@wp.kernel(enable_backward=False)
def gather_blur(width: int, height: int, color: wp.array(dtype=wp.vec4), depth: wp.array(dtype=float),
                vhalf: wp.array(dtype=wp.vec2), neighbor_max: wp.array(dtype=wp.vec2), tile: int, tiles_x: int,
                samples: int, sigma: float, seed: int, first_pixel: int,
                # outputs
                out: wp.array2d(dtype=float)):
    """Reconstruct the blurred pixel from the sharp colour, depth and half-velocity buffers."""
    pix = first_pixel + wp.tid()
    px = pix % width
    py = pix // width
    vn = neighbor_max[(py // tile) * tiles_x + px // tile]
    cx = color[pix]
    result = cx
    if wp.length(vn) > 0.5:
        zx = depth[pix]
        vx = vhalf[pix]
        lx = wp.max(wp.length(vx), 0.5)
        w_sum = 1.0 / lx
        acc = cx * w_sum
        state = wp.rand_init(seed, pix)
        jitter = wp.randf(state) - 0.5
        ln = wp.length(vn)
        for i in range(samples):
            t = -1.0 + 2.0 * (float(i) + jitter + 1.0) / float(samples + 1)
            sx = int(wp.floor(float(px) + 0.5 + vn[0] * t))
            sy = int(wp.floor(float(py) + 0.5 + vn[1] * t))
            if sx >= 0 and sx < width and sy >= 0 and sy < height and not (sx == px and sy == py):
                q = sy * width + sx
                zy = depth[q]
                vy = wp.length(vhalf[q])
                dist = ln * wp.abs(t)
                f = soft_depth_compare(zy, zx)
                b = soft_depth_compare(zx, zy)
                a = f * cone(dist, vy) + b * cone(dist, lx) + cylinder(dist, vy) * cylinder(dist, lx) * 2.0
                a = a * wp.exp(-0.5 * t * t / (sigma * sigma))
                w_sum = w_sum + a
                acc = acc + color[q] * a
        result = acc / w_sum
    out[pix, 0] = result[0]
    out[pix, 1] = result[1]
    out[pix, 2] = result[2]
    out[pix, 3] = result[3]


def camera_motion_from_depth(ctx: FrameContext, depth: np.ndarray, cfw_open: np.ndarray, cfw_center: np.ndarray,
                             cfw_close: np.ndarray) -> np.ndarray:
    """(H, W, 2) screen motion (pixels, open -> close) of static points seen at `depth`, from the
    camera's motion alone: unproject with the centre camera, reproject with open and close (where
    nothing is hit, the direction of the pixel's ray: the dome turns with the camera)."""
    proj = ctx.proj
    h, w = depth.shape
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float64) + 0.5
    wx, wy = proj.pixel_window_coords(xs, ys)
    z = np.where(np.isfinite(depth), depth, 0.0).astype(np.float64)
    if proj.orthographic:
        p = np.stack([wx, wy, -z, np.ones_like(z)], -1)
    else:
        p = np.stack([wx * z, wy * z, -z, np.ones_like(z)], -1)
    far = ~np.isfinite(depth)
    if not proj.orthographic:
        # nothing hit: the dome, infinitely far, moves with the camera's turn alone (a direction, w = 0)
        p[far] = np.stack([wx[far], wy[far], -np.ones(far.sum()), np.zeros(far.sum())], -1)
    center_to_world = invert_affine(cfw_center)
    p_open = (p @ (center_to_world @ cfw_open))[..., :3]
    p_close = (p @ (center_to_world @ cfw_close))[..., :3]
    with np.errstate(divide="ignore", invalid="ignore"):
        motion = proj.project(p_close) - proj.project(p_open)
    behind = far & ((p_open[..., 2] >= 0) | (p_close[..., 2] >= 0))    # a turn of 90° or more
    motion[~np.isfinite(motion).all(-1) | behind | (far & proj.orthographic)] = 0.0
    return motion


def normals_from_depth(ctx: FrameContext, depth: np.ndarray) -> np.ndarray:
    """(H, W, 3) camera-space normals from depth-buffer gradients (zero where unknown)."""
    proj = ctx.proj
    h, w = depth.shape
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float64) + 0.5
    wx, wy = proj.pixel_window_coords(xs, ys)
    z = np.where(np.isfinite(depth), depth, np.nan)
    p = np.stack([wx * z, wy * z, -z], -1) if not proj.orthographic else np.stack([wx, wy, -z], -1)
    dx = np.gradient(p, axis=1)
    dy = np.gradient(p, axis=0)
    n = np.cross(dy, dx)
    n /= np.linalg.norm(n, axis=-1, keepdims=True) + 1e-30
    return np.nan_to_num(n)


def box_blur(a: np.ndarray, r: int, axis: int) -> np.ndarray:
    """Mean over a (2r+1)-wide window along `axis`, zeros beyond the edges (a convolution with a
    box kernel, mode "same"), from cumulative sums."""
    a = np.moveaxis(a, axis, 0)
    n = a.shape[0]
    c = np.concatenate([np.zeros((1,) + a.shape[1:]), np.cumsum(a, axis=0)])
    i = np.arange(n)
    out = (c[np.minimum(i + r + 1, n)] - c[np.maximum(i - r, 0)]) / (2 * r + 1)
    return np.moveaxis(out, 0, axis)


def soft_edge_velocity(v: np.ndarray, radius: float) -> np.ndarray:
    """Velocity spread past silhouettes: half-res box blur of (v·mask, mask), mask divided out."""
    if radius <= 0:
        return v
    h, w, _ = v.shape
    h2, w2 = (h + 1) // 2, (w + 1) // 2
    pad = np.zeros((h2 * 2, w2 * 2, 2))
    pad[:h, :w] = v
    low = pad.reshape(h2, 2, w2, 2, 2).mean(axis=(1, 3))
    mask = (np.linalg.norm(low, axis=-1) > 1e-3).astype(np.float64)
    r = max(1, int(round(radius / 2)))

    def blur(a):
        return box_blur(box_blur(a, r, 0), r, 1)
    num = np.stack([blur(low[..., 0] * mask), blur(low[..., 1] * mask)], -1)
    den = blur(mask)[..., None]
    soft = np.where(den > 1e-6, num / np.maximum(den, 1e-6), 0.0)
    up = soft.repeat(2, axis=0).repeat(2, axis=1)[:h, :w]
    moving = np.linalg.norm(v, axis=-1, keepdims=True) > 1e-3
    return np.where(moving, v, up)


def tile_neighbor_max(vhalf: np.ndarray, tile: int) -> tuple[np.ndarray, int]:
    """(tiles_y*tiles_x, 2) neighbour-max half velocities (largest in each 3×3 block of tile maxima)."""
    h, w, _ = vhalf.shape
    ty, tx = (h + tile - 1) // tile, (w + tile - 1) // tile
    pad = np.zeros((ty * tile, tx * tile, 2))
    pad[:h, :w] = vhalf
    blocks = pad.reshape(ty, tile, tx, tile, 2).transpose(0, 2, 1, 3, 4).reshape(ty, tx, tile * tile, 2)
    idx = np.linalg.norm(blocks, axis=-1).argmax(axis=-1)
    tmax = np.take_along_axis(blocks, idx[..., None, None], axis=2)[:, :, 0]
    padded = np.zeros((ty + 2, tx + 2, 2))
    padded[1:-1, 1:-1] = tmax
    cands = np.stack([padded[1 + dy:1 + dy + ty, 1 + dx:1 + dx + tx] for dy in (-1, 0, 1) for dx in (-1, 0, 1)], 2)
    best = np.linalg.norm(cands, axis=-1).argmax(axis=-1)
    nmax = np.take_along_axis(cands, best[..., None, None], axis=2)[:, :, 0]
    return nmax.reshape(-1, 2), tx


#: sharp passes the velocity method averages where opacity is fractional: presence at consecutive
#: slots of each triangle's sequence (stratified), so translucency is smooth rather than a dither
PRESENCE_PASSES = 8
#: tests switch this off to compare against presence passes over every pixel
PRESENCE_TILES = True


def presence_pixels(bins, entry_fractional: np.ndarray, tile_size: int, width: int, height: int) -> np.ndarray:
    """Flat indices (ascending, int32) of the pixels in screen tiles whose bins hold an entry with
    fractional opacity (entry_fractional (E,) bool): the only pixels a presence pass can change."""
    counts = np.diff(bins.tile_offsets)
    tile_of_pair = np.repeat(np.arange(len(counts)), counts)
    flagged = np.zeros(len(counts), bool)
    flagged[tile_of_pair[entry_fractional[bins.tile_entries]]] = True
    return tile_mask_pixels(flagged.reshape(bins.tiles_y, bins.tiles_x), tile_size, width, height).astype(np.int32)


def presence_passes(ctx: FrameContext, view, geo, sh, bins, u: float, first_pass: wp.array,
                    pixels: np.ndarray) -> wp.array:
    """(H*W, 4) the mean of first_pass (presence slot shift 0, which also gave depth and motion)
    and PRESENCE_PASSES - 1 more sharp renders of the same instant, each with the fractional
    surfaces' presence at the next slot of their sequences. Only `pixels` (presence_pixels) are
    rendered again: elsewhere every pass equals the first, and its sum is formed as the passes'
    additions would form it."""
    dev = ctx.device
    more = wp.zeros_like(first_pass)
    listed = wp.array(pixels, dtype=int, device=dev)
    rec_e, rec_hit = wp.zeros((1, 1), dtype=int, device=dev), wp.zeros((1, 1), dtype=wp.vec4, device=dev)
    done = wp.zeros(1, dtype=wp.uint8, device=dev)
    with ctx.timed("render"):
        for j in range(1, PRESENCE_PASSES):
            geo.presence_shift = j
            launch_pixels(render_sharp, len(pixels),
                          lambda first, _n: [view, geo, sh, bins, u, 1.0, listed, 1, first, 0, more, rec_e, rec_hit,
                                             done],
                          dev, ctx.settings.threads)
        geo.presence_shift = 0
    ctx.counters["presence_passes"] = PRESENCE_PASSES
    ctx.counters["presence_pixels"] = len(pixels) / max(1, ctx.num_pixels)
    once = first_pass.numpy()
    total = more.numpy()
    repeated = np.zeros_like(once)
    for _ in range(1, PRESENCE_PASSES):
        repeated += once
    others = np.ones(len(once), bool)
    others[pixels] = False
    total[others] = repeated[others]
    return wp.array((once + total) / PRESENCE_PASSES, dtype=float, device=dev)


def render_velocity(ctx: FrameContext) -> np.ndarray:
    s = ctx.settings
    dev = ctx.device
    h, w = ctx.proj.height, ctx.proj.width
    snaps = [ctx.snapshot(0.0), ctx.snapshot(0.5), ctx.snapshot(1.0)]
    cfw = [sn.cam_from_world for sn in snaps]
    camera_moves = not (np.array_equal(cfw[0], cfw[1]) and np.array_equal(cfw[1], cfw[2]))
    with ctx.timed("velocity"):
        # vertex positions at open and close seen from the centre camera (object motion only)
        to_center = [invert_affine(c) @ cfw[1] for c in cfw]
        knots = [sn.positions @ m[:3, :3] + m[3, :3] for sn, m in zip(snaps, to_center)]
        center = snaps[1]
        if s.velocity_extrude:
            n = vertex_normals(center.positions, ctx.scene.tri_vertices)
            forward = np.einsum("ij,ij->i", n, knots[2] - knots[0]) > 0
            center.positions = np.where(forward[:, None], knots[2], knots[0])
            knots[1] = center.positions
    # sharp colour at the shutter centre (possibly with extruded trails), depth and object motion:
    # one visibility pass (two when spatial samples need the colour at several sub-pixel positions)
    sharp = wp.zeros((ctx.num_pixels, 4), dtype=float, device=dev)
    positions = np.stack(knots)
    normals = np.stack([center.normals] * 3) if ctx.scene.any_smooth else None
    tris = np.nonzero(center.tri_visible)[0].astype(np.int32)
    k = np.full(len(tris), 1, np.int32)
    geo = make_geometry(ctx.tables, positions, normals, tris, k, k)
    tile_bins = ctx.bin(positions, tris, k, k)
    view, b = ctx.view(tile_bins), make_bins(tile_bins, dev)
    depth_w = wp.zeros(ctx.num_pixels, dtype=float, device=dev)
    motion_w = wp.zeros(ctx.num_pixels, dtype=wp.vec2, device=dev)
    u = ctx.shutter_fraction(center.time)
    if s.spatial_samples == 1:
        sh = ctx.shading([center])
        with ctx.timed("render"):
            launch_pixels(render_sharp_depth_motion, ctx.num_pixels,
                          lambda first, _n: [view, geo, sh, b, u, 0, 2, first, sharp, depth_w, motion_w], dev,
                          s.threads)
        if ctx.scene.any_fractional:
            fractional = ctx.scene.tri_fractional[tris]
            pixels = (presence_pixels(tile_bins, fractional, view.tile_size, w, h) if PRESENCE_TILES
                      else np.arange(ctx.num_pixels, dtype=np.int32))
            sharp = presence_passes(ctx, view, geo, sh, b, u, sharp, pixels)
    else:
        ctx.sharp_pass(center, 1.0, sharp, cull=not s.velocity_extrude)   # extruded trails fold surfaces
        with ctx.timed("velocity"):
            launch_pixels(render_depth_motion, ctx.num_pixels,
                          lambda first, _n: [view, geo, b, u, 0, 2, first, depth_w, motion_w], dev, s.threads)
    with ctx.timed("velocity"):
        depth = depth_w.numpy().reshape(h, w)
        velocity = motion_w.numpy().reshape(h, w, 2).astype(np.float64)
        if camera_moves:
            velocity += camera_motion_from_depth(ctx, depth, cfw[0], cfw[1], cfw[2])
        ctx.aov_motion = velocity.astype(np.float32)
        ctx.aov_depth = depth.astype(np.float32)
        if s.front_blur != 1.0 or s.back_blur != 1.0:
            n = normals_from_depth(ctx, depth)
            # screen-space facing: the normal's x/y (y down on screen) against the motion
            facing = n[..., 0] * velocity[..., 0] - n[..., 1] * velocity[..., 1]
            velocity *= np.where(facing >= 0, s.front_blur, s.back_blur)[..., None]
        velocity = soft_edge_velocity(velocity, s.soft_edge_radius)
        vhalf = 0.5 * velocity
        max_r = float(np.linalg.norm(vhalf, axis=-1).max()) if vhalf.size else 0.0
        tile = int(np.clip(np.ceil(max_r), 8, 64))
        nmax, tiles_x = tile_neighbor_max(vhalf, tile)
    if max_r <= 0.5:
        ctx.counters.update({"velocity_max_px": 2 * max_r, "gather": False})
        return sharp.numpy()
    out = wp.zeros((ctx.num_pixels, 4), dtype=float, device=dev)
    color = wp.array(sharp.numpy().astype(np.float32), dtype=wp.vec4, device=dev)
    z = wp.array(np.where(np.isfinite(depth), depth, 1e30).astype(np.float32).ravel(), dtype=float, device=dev)
    vh = wp.array(vhalf.reshape(-1, 2).astype(np.float32), dtype=wp.vec2, device=dev)
    nm = wp.array(nmax.astype(np.float32), dtype=wp.vec2, device=dev)
    samples = s.resolved_samples
    with ctx.timed("gather"):
        launch_pixels(gather_blur, ctx.num_pixels,
                      lambda first, _n: [w, h, color, z, vh, nm, tile, tiles_x, samples, 0.5, 1, first, out],
                      dev, s.threads)
    ctx.counters.update({"velocity_max_px": 2 * max_r, "gather": True, "gather_samples": samples,
                         "velocity_tile": tile, "camera_motion": camera_moves})
    return out.numpy()
