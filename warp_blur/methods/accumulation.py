"""Accumulation, the reference: N sharp instants at u_i = (i + 0.5)/N, averaged (SPEC §5)."""

from __future__ import annotations

import numpy as np
import warp as wp

from ..frame import FrameContext


def instants(n: int) -> np.ndarray:
    """Shutter fractions of the N accumulation instants."""
    return (np.arange(n) + 0.5) / n


def render_accumulation(ctx: FrameContext) -> np.ndarray:
    n = ctx.settings.resolved_samples
    if ctx.shutter.instant:
        n = 1  # every instant is the same one
    rgba = wp.zeros((ctx.num_pixels, 4), dtype=float, device=ctx.device)
    ctx.instants = n
    for u in instants(n):
        ctx.sharp_pass(ctx.snapshot(float(u)), 1.0 / n, rgba)
    ctx.counters["instants"] = n
    return rgba.numpy()
