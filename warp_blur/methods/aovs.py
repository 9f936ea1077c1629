"""The Z and motion AOVs (SPEC §1) of a frame whose method does not write its own: a sharp pass
of their own at the shutter centre, from positions at open, centre and close (the velocity
method, and a still frame's render, write them from their own visibility pass instead)."""

from __future__ import annotations

import numpy as np
import warp as wp

from ..core.parallel import launch_pixels
from ..kernels.raster import render_depth_motion
from ..raster.device_data import make_bins
from ..usd.scene import Snapshot
from .frame import FrameContext

#: the shutter fractions of the snapshots the AOVs are rendered from (open, centre, close)
AOV_FRACTIONS = (0.0, 0.5, 1.0)


def aov_snapshots(ctx: FrameContext) -> list[Snapshot]:
    """The snapshots the AOVs are rendered from (AOV_FRACTIONS), positions only: static_frame's
    probes where they took them, the others taken now and kept with the probes (where a method's
    motion plan reuses them)."""
    for u in AOV_FRACTIONS:
        if u not in ctx.probe_snapshots:
            ctx.probe_snapshots[u] = ctx.snapshot(u, with_normals=u == 0.5)   # the centre's keeps normals
    return [ctx.probed_snapshot(u, with_normals=False) for u in AOV_FRACTIONS]


def depth_motion(ctx: FrameContext, snapshots: list[Snapshot] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Z (H, W) and motion (H, W, 2) of the surface seen at the shutter centre (snapshots:
    aov_snapshots()'s, taken here when not given). Given them, it reads no USD and leaves the
    frame's counters alone, so it may run beside the method (api.py)."""
    if snapshots is None:
        snapshots = aov_snapshots(ctx)
    geo, bins = ctx.static_geometry(snapshots, 1, shaded=False, counted=False)
    view, b = ctx.view(bins), make_bins(bins, ctx.device)
    depth = wp.zeros(ctx.num_pixels, dtype=float, device=ctx.device)
    motion = wp.zeros(ctx.num_pixels, dtype=wp.vec2, device=ctx.device)
    no_gather = wp.zeros(0, dtype=wp.vec2, device=ctx.device)
    with ctx.timed("aovs"):
        launch_pixels(render_depth_motion, ctx.num_pixels,
                      lambda first, _n: [view, geo, b, 0.5, 0, 2, first, depth, motion, no_gather],
                      ctx.device, ctx.settings.threads)
    h, w = ctx.proj.height, ctx.proj.width
    return depth.numpy().reshape(h, w), motion.numpy().reshape(h, w, 2)
