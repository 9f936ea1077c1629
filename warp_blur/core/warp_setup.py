"""Warp's settings for this package, applied on import: whichever module first uses Warp (a kernel
module, or host code that builds Warp arrays, such as the scene's vertex normals behind
`warp-blur info`) imports this first, so Warp starts without printing its greeting on stdout."""

from __future__ import annotations

import warp as wp

wp.config.log_level = wp.LOG_WARNING
