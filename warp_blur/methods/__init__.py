"""Motion-blur methods, registered by name (SPEC §5). Each takes a FrameContext and returns the
image as (H*W, 4) float32 RGBA plus method statistics; they differ only in how visibility over
time is resolved."""

from __future__ import annotations

from typing import Callable

import numpy as np

from .frame import FrameContext

MethodFn = Callable[[FrameContext], np.ndarray]


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
