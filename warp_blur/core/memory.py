"""What a frame's per-pixel buffers cost, so that a frame too large for this machine is refused
before anything is allocated (a 100000x100000 image must not start rendering).

The bytes per pixel are measured peaks over the fixed start-up cost (demo.usda, 512x384 against
2048x1536, `/usr/bin/time -f %M`), rounded up; the analytic interval arrays are chunked to
`memory_budget_mb` separately and are not counted here. Triangles add their tables.
"""

from __future__ import annotations

import os

from .errors import SettingsError

#: Peak bytes per output pixel and per spatial sub-sample, by method (measured: accumulation 17,
#: stochastic 49, analytic 350 with its chunked intervals, velocity 243).
BYTES_PER_PIXEL = {"accumulation": 32, "stochastic": 64, "analytic": 384, "velocity": 320}
#: Device tables per triangle (positions over the shutter, shading corners, bins).
BYTES_PER_TRIANGLE = 160
#: Tables per entry of the methods that plan motion (analytic, stochastic): the edge table (11
#: vec3, methods/analytic/coverage.py) and the corner table (6 vec3, methods/analytic/moving.py).
#: A triangle is at least one entry (one per motion segment where it moves).
ENTRY_TABLE_BYTES = {"analytic": (11 + 6) * 12, "stochastic": (11 + 6) * 12}


def frame_bytes(method: str, width: int, height: int, spatial_samples: int = 1, triangles: int = 0) -> int:
    """Estimated peak bytes of one frame's buffers (pixels x sub-samples, plus triangle tables,
    with each triangle counted as one entry)."""
    return int(BYTES_PER_PIXEL[method] * width * height * max(1, spatial_samples) ** 2
               + (BYTES_PER_TRIANGLE + ENTRY_TABLE_BYTES.get(method, 0)) * triangles)


def physical_memory_bytes() -> int | None:
    """This machine's physical memory, or None where the OS does not say."""
    try:
        return int(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (AttributeError, ValueError, OSError):
        return None


def default_limit_mb() -> float:
    """Three quarters of physical memory (16 GiB where it cannot be read)."""
    total = physical_memory_bytes()
    return 0.75 * total / 2**20 if total else 16384.0


def _size(nbytes: float) -> str:
    """Bytes as GiB, or MiB below one GiB (a limit of 0.3 MiB is not '0.0 GiB')."""
    return f"{nbytes / 2**30:.1f} GiB" if nbytes >= 2**30 else f"{nbytes / 2**20:.2f} MiB"


def check_frame_fits(method: str, width: int, height: int, spatial_samples: int, limit_mb: float | None) -> None:
    """A SettingsError naming the estimate and the limit when the frame would not fit."""
    limit = default_limit_mb() if limit_mb is None else float(limit_mb)
    need = frame_bytes(method, width, height, spatial_samples)
    if need > limit * 2**20:
        raise SettingsError(
            f"a {width}x{height} frame with {method}"
            f"{f' and {spatial_samples}x{spatial_samples} spatial samples' if spatial_samples > 1 else ''} "
            f"needs about {_size(need)}, over the memory limit of {_size(limit * 2**20)} "
            f"(lower --resolution or raise --memory-limit)")


def check_entries_fit(method: str, width: int, height: int, spatial_samples: int, triangles: int, entries: int,
                      limit_mb: float | None) -> None:
    """Once the motion plan is known (before its tables are allocated): a SettingsError when the
    frame's pixels, triangle tables and its entries (a triangle one per motion segment) would not
    fit the memory limit. check_frame_fits, before the stage is read, counts pixels only."""
    limit = default_limit_mb() if limit_mb is None else float(limit_mb)
    need = frame_bytes(method, width, height, spatial_samples, triangles) \
        + ENTRY_TABLE_BYTES.get(method, 0) * max(0, entries - triangles)
    if need > limit * 2**20:
        raise SettingsError(
            f"this frame's {triangles} triangles in {entries} motion entries need about {_size(need)} "
            f"with its {width}x{height} pixels, over the memory limit of {_size(limit * 2**20)} (raise "
            f"--memory-limit, or lower RenderSettings.max_segments)")
