"""Motion-blur methods, registered by name (SPEC §5). Each takes a FrameContext and returns the
image as (H*W, 4) float32 RGBA plus method statistics; they differ only in how visibility over
time is resolved."""

from __future__ import annotations

from typing import Callable

import numpy as np

from .frame import FrameContext

MethodFn = Callable[[FrameContext], np.ndarray]


#: kernel modules used by every method (the sharp and shadow-map rasterisers, back-face culling,
#: tile lists, the shadow casters' triangle sizes, vertex normals, the shadow set-up's vertex
#: passes), the longest to build first
_SHARED = ("warp_blur.kernels.raster", "warp_blur.kernels.shadow_raster", "warp_blur.raster.tile_lists",
           "warp_blur.raster.culling", "warp_blur.raster.triangle_sizes", "warp_blur.usd.normals",
           "warp_blur.shadows.vertex_passes")

#: the Warp modules each method's frames launch kernels of (core/preload.py builds them side by side
#: before the first frame; tests/test_preload.py checks each list against the modules a method loads
#: by itself), the longest to build first
KERNEL_MODULES: dict[str, tuple[str, ...]] = {
    "accumulation": _SHARED + ("warp_blur.kernels.shadow_free",),
    "stochastic": ("warp_blur.methods.stochastic",) + _SHARED + (
        "warp_blur.methods.analytic.coverage", "warp_blur.kernels.shadow_free", "warp_blur.raster.screen_bounds",
        "warp_blur.methods.analytic.moving", "warp_blur.methods.analytic.chords"),
    "analytic": ("warp_blur.methods.analytic.intervals", "warp_blur.methods.analytic.resolve") + _SHARED + (
        "warp_blur.methods.analytic.coverage", "warp_blur.kernels.shadow_free", "warp_blur.raster.screen_bounds",
        "warp_blur.methods.analytic.moving", "warp_blur.methods.analytic.chords"),
    "velocity": _SHARED + ("warp_blur.methods.velocity_buffers", "warp_blur.methods.velocity"),
}


def get_method(name: str) -> MethodFn:
    if name == "accumulation":
        from .accumulation import render_accumulation
        return render_accumulation
    if name == "stochastic":
        from .stochastic import render_stochastic
        return render_stochastic
    if name == "analytic":
        from .analytic import render_analytic
        return render_analytic
    if name == "velocity":
        from .velocity import render_velocity
        return render_velocity
    raise KeyError(name)
