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
  over what is in front of it; the samples' weights are scaled by 9/(N + 1) against the centre's
  (GATHER_CALIBRATION_SAMPLES), so N sets how smooth the blur is, not how much there is.
- Vertex-trail extrusion (option): vertices whose normals face their motion are placed at
  shutter close, the others at open, stretching silhouettes before the gather.
- A point behind the eye at open or close has no screen displacement (motion AOV 0); the blur
  takes twice its motion over the half of the shutter it is seen in (gather_w).
Known limits: blur from shading changes (a moving shadow on a static receiver, a moving light)
cannot appear, since only geometry has velocity; overlapping motions are approximated.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import warp as wp

from ..raster.binning import tile_mask_pixels
from ..raster.device_data import make_bins, make_geometry
from .frame import FrameContext
from ..core.parallel import Background, default_threads, launch_pixels
from ..core.affine import invert_affine
from ..kernels.raster import render_depth_motion, render_sharp, render_sharp_depth_motion
from ..usd.normals import vertex_normals
from .velocity_buffers import camera_motion, neighbour_maxima, soft_half_velocities, tile_maxima

SOFT_Z = wp.constant(0.01)
#: the gather's sample count at which each sample weighs in as McGuire et al. weigh it; with N
#: samples each weighs (this + 1)/(N + 1) of that, so that together they stand for the same length
#: of the velocity against the centre pixel's fixed weight whatever N is: more samples then
#: smooth the same blur instead of adding blur (and their error falls with N on every bench stage;
#: unscaled, rotation's rose from 0.089 at 8 to 0.124 at 64). 8: the default, whose images this
#: leaves as they were.
GATHER_CALIBRATION_SAMPLES = 8


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


#: the depth a pixel with nothing hit (inf) gathers with: far behind everything, and finite
FAR_Z = wp.constant(1.0e30)


@wp.func
def gather_depth(depth: wp.array(dtype=float), pix: int) -> float:
    z = depth[pix]
    if wp.isfinite(z):
        return z
    return FAR_Z


@wp.func
def pixel_color(color: wp.array2d(dtype=float), pix: int) -> wp.vec4:
    return wp.vec4(color[pix, 0], color[pix, 1], color[pix, 2], color[pix, 3])


@wp.kernel(enable_backward=False)
def gather_blur(width: int, height: int, color: wp.array2d(dtype=float), depth: wp.array(dtype=float),
                vhalf: wp.array(dtype=wp.vec2), neighbor_max: wp.array(dtype=wp.vec2), tile: int, tiles_x: int,
                samples: int, sample_weight: float, sigma: float, seed: int, first_pixel: int,
                # outputs
                out: wp.array2d(dtype=float)):
    """Reconstruct the blurred pixel from the sharp colour ((H*W, 4)), view depth (inf where nothing
    is hit: FAR_Z) and half-velocity buffers, read where the passes wrote them."""
    pix = first_pixel + wp.tid()
    px = pix % width
    py = pix // width
    vn = neighbor_max[(py // tile) * tiles_x + px // tile]
    cx = pixel_color(color, pix)
    result = cx
    if wp.length(vn) > 0.5:
        zx = gather_depth(depth, pix)
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
                zy = gather_depth(depth, q)
                vy = wp.length(vhalf[q])
                dist = ln * wp.abs(t)
                f = soft_depth_compare(zy, zx)
                b = soft_depth_compare(zx, zy)
                a = f * cone(dist, vy) + b * cone(dist, lx) + cylinder(dist, vy) * cylinder(dist, lx) * 2.0
                a = a * wp.exp(-0.5 * t * t / (sigma * sigma)) * sample_weight
                w_sum = w_sum + a
                acc = acc + pixel_color(color, q) * a
        result = acc / w_sum
    out[pix, 0] = result[0]
    out[pix, 1] = result[1]
    out[pix, 2] = result[2]
    out[pix, 3] = result[3]


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
    # open and close need positions only (normals come from the centre), as static_frame probed them
    snaps = [ctx.probed_snapshot(0.0, with_normals=False), ctx.probed_snapshot(0.5),
             ctx.probed_snapshot(1.0, with_normals=False)]
    cfw = [sn.cam_from_world for sn in snaps]
    camera_moves = not (np.array_equal(cfw[0], cfw[1]) and np.array_equal(cfw[1], cfw[2]))
    with ctx.timed("velocity"):
        # vertex positions at open and close seen from the centre camera (object motion only)
        to_center = [invert_affine(c) @ cfw[1] for c in cfw]
        knots = [sn.positions @ m[:3, :3] + m[3, :3] for sn, m in zip(snaps, to_center)]
        center = snaps[1]
        if s.velocity_extrude:
            center = dataclasses.replace(center)   # the probes' snapshot is shared
            n = vertex_normals(center.positions, ctx.scene.tri_vertices)
            forward = np.einsum("ij,ij->i", n, knots[2] - knots[0]) > 0
            center.positions = np.where(forward[:, None], knots[2], knots[0])
            knots[1] = center.positions
    # the centre's shading, shadow maps included (their set-up and rendering), built on a helper
    # thread beside the geometry and binning below, as analytic's and stochastic's maps are; in
    # turn when no light casts a shadow or one core is asked for
    shading_job = None
    # the method sees the scene at open, centre and close only (the maps at the centre, extruded
    # trails at open or close): those three bound every point a lookup or a map reads, so a light
    # whose shadows fall on nothing lit there gets no maps (shadows/pairs.py; a moving camera
    # moves the light in camera space between them, which keeps its maps)
    ctx.instant_knots = snaps
    if s.spatial_samples == 1 and ctx.may_cast_shadows() and (s.threads or default_threads()) > 1:
        _ = ctx.tables   # made here, not raced for by the helper and the geometry below
        shading_job = Background(lambda: ctx.shading([center]), "shadows")
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
    # the blur's velocity: the motion, and where a point passes behind the eye (no motion AOV)
    # twice its motion over the half of the shutter it is seen in
    gather_w = wp.zeros(ctx.num_pixels, dtype=wp.vec2, device=dev)
    u = ctx.shutter_fraction(center.time)
    if s.spatial_samples == 1:
        sh = shading_job.result() if shading_job is not None else ctx.shading([center])
        with ctx.timed("render"):
            launch_pixels(render_sharp_depth_motion, ctx.num_pixels,
                          lambda first, _n: [view, geo, sh, b, u, 0, 2, first, sharp, depth_w, motion_w, gather_w],
                          dev, s.threads)
        if ctx.scene.any_fractional:
            fractional = ctx.scene.tri_fractional[tris]
            pixels = (presence_pixels(tile_bins, fractional, view.tile_size, w, h) if PRESENCE_TILES
                      else np.arange(ctx.num_pixels, dtype=np.int32))
            sharp = presence_passes(ctx, view, geo, sh, b, u, sharp, pixels)
    else:
        ctx.sharp_pass(center, 1.0, sharp, cull=not s.velocity_extrude)   # extruded trails fold surfaces
        with ctx.timed("velocity"):
            launch_pixels(render_depth_motion, ctx.num_pixels,
                          lambda first, _n: [view, geo, b, u, 0, 2, first, depth_w, motion_w, gather_w], dev,
                          s.threads)
    threads = s.threads
    with ctx.timed("velocity"):
        if camera_moves:
            # the motion AOV and the blur's velocity (half_seen) from one pass
            camera_motion(depth_w, motion_w, ctx.proj, invert_affine(cfw[1]) @ cfw[0],
                          invert_affine(cfw[1]) @ cfw[2], dev, threads, seen_motion=gather_w)
        # copies: the device buffers go back to the allocator when the frame ends
        depth = depth_w.numpy().reshape(h, w).copy()
        ctx.aov_depth = depth
        ctx.aov_motion = motion_w.numpy().reshape(h, w, 2).copy()
        velocity = gather_w
        if s.front_blur != 1.0 or s.back_blur != 1.0:
            v = gather_w.numpy().reshape(h, w, 2).astype(np.float64)
            n = normals_from_depth(ctx, depth)
            # screen-space facing: the normal's x/y (y down on screen) against the motion
            facing = n[..., 0] * v[..., 0] - n[..., 1] * v[..., 1]
            v *= np.where(facing >= 0, s.front_blur, s.back_blur)[..., None]
            velocity = wp.array(v.reshape(-1, 2).astype(np.float32), dtype=wp.vec2, device=dev)
        vh = soft_half_velocities(velocity, w, h, s.soft_edge_radius, dev, threads)
        # the longest half velocity (from 8-pixel tiles) sets the tiles' size: the largest blur radius
        tmax, tiles_x, tiles_y = tile_maxima(vh, w, h, 8, dev, threads)
        max_r = float(np.linalg.norm(tmax.numpy().astype(np.float64), axis=-1).max()) if w * h else 0.0
        tile = int(np.clip(np.ceil(max_r), 8, 64))
        if tile != 8:
            tmax, tiles_x, tiles_y = tile_maxima(vh, w, h, tile, dev, threads)
        nm = neighbour_maxima(tmax, tiles_x, tiles_y, dev, threads)
    if max_r <= 0.5:
        ctx.counters.update({"velocity_max_px": 2 * max_r, "gather": False})
        return sharp.numpy()
    out = wp.zeros((ctx.num_pixels, 4), dtype=float, device=dev)
    samples = s.resolved_samples
    sample_weight = (GATHER_CALIBRATION_SAMPLES + 1.0) / (samples + 1.0)
    with ctx.timed("gather"):   # the sharp colour and depth as the passes left them, on the device
        launch_pixels(gather_blur, ctx.num_pixels,
                      lambda first, _n: [w, h, sharp, depth_w, vh, nm, tile, tiles_x, samples, sample_weight, 0.5, 1,
                                         first, out],
                      dev, threads)
    ctx.counters.update({"velocity_max_px": 2 * max_r, "gather": True, "gather_samples": samples,
                         "velocity_tile": tile, "camera_motion": camera_moves})
    return out.numpy()
