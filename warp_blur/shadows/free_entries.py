"""Flag the entries no shadow can fall on, so shading skips their lookups (kernels/shadow_free.py).

A lit frame's receivers are mostly far from any shadow, and each lookup is a chain of loads and a
transform; a conservative test per entry and light, once a frame (analytic, stochastic) or once
a sharp instant (accumulation's sharp passes), replaces those lookups by their value there (lit).
The flags go in the Geometry whose entries they describe, set against one Shading's maps."""

from __future__ import annotations

import threading
from typing import Callable

import numpy as np
import warp as wp

from ..core.parallel import launch_pixels
from ..kernels.kernel_types import Geometry, Shading
from ..kernels.shadow_free import block_occupancy, entry_shadow_free

#: texels per side of an occupancy block (the test's resolution in the maps)
BLOCK = 4
#: tests switch this off to compare against looking every lookup up
SKIP_SHADOW_FREE = True
#: most flags (entries × lights, int32) a frame keeps; past it every lookup is made
MAX_FLAGS = 1 << 23


def occupancy_table(sh: Shading, device: str, threads: int | None,
                    blocks: np.ndarray | None = None) -> wp.array | None:
    """(slots, G+1, G+1) int32 summed-area tables of the BLOCK² texel blocks of each face slot
    that hold a caster's depth at some map instant (G = ceil(S / BLOCK)); None where the entries
    are not to be tested (switched off, or no maps). blocks: those blocks (slots, G, G), marked as
    the maps were written (TexelMajorLayout.occupancy); without them the maps are read."""
    maps = sh.shadow_maps
    if not SKIP_SHADOW_FREE or maps.shape[1] <= 1:
        return None
    slots, size = maps.shape[0], maps.shape[1]
    g = -(-size // BLOCK)
    if blocks is not None and blocks.shape != (slots, g, g):
        blocks = None   # marked at another block size
    if blocks is None:
        occupied = wp.zeros((slots, g, g), dtype=int, device=device)
        launch_pixels(block_occupancy, slots * g, lambda first, _n: [maps, BLOCK, g, first, occupied], device,
                      threads)
        blocks = occupied.numpy()
    table = np.zeros((slots, g + 1, g + 1), np.int32)
    table[:, 1:, 1:] = blocks.astype(np.int32).cumsum(axis=1).cumsum(axis=2)
    return wp.array(table, dtype=int, device=device)


def testable_lights(sh: Shading, sharp: bool = False) -> int:
    """Bits of the lights whose entries may be flagged: those with maps, and with one map instant
    (outside a sharp instant) only those that hold still (their lookups then read the light's
    frame at every time)."""
    lights = sh.shadow_lights.numpy()
    still_needed = sh.shadow_times == 1 and not sharp
    table = sh.lights.numpy() if still_needed else None   # (knots, NL, width)
    bits = 0
    for j in range(min(sh.num_lights, 31)):
        if lights[j, 0] < 0:
            continue
        if still_needed and not (table[:, j] == table[:1, j]).all():
            continue
        bits |= 1 << j
    return bits


def flag_shadow_free(sh: Shading, occ: wp.array | None, geo: Geometry, num_entries: int, device: str,
                     counters: dict | None = None, sharp_at: float | None = None) -> None:
    """Set geo.shadow_free for geo's num_entries entries (bit j: light j's lookups skipped),
    from the maps' occupancy table occ (occupancy_table; None: nothing flagged). sharp_at: the
    shutter time of a sharp instant whose static entries geo holds (accumulation), else None."""
    if occ is None or num_entries == 0 or num_entries * sh.num_lights > MAX_FLAGS:
        return
    bits = testable_lights(sh, sharp_at is not None)
    if bits == 0:
        return
    flags = wp.empty(num_entries * sh.num_lights, dtype=int, device=device)
    # one launch (a few ms), never the thread pool: the first shading() may be called from a
    # pool worker (analytic's bands), which would wait on its own pool
    wp.launch(entry_shadow_free, dim=num_entries,
              inputs=[geo, sh, occ, BLOCK, bits, int(sharp_at is not None), float(sharp_at or 0.0), flags],
              device=device)
    geo.shadow_free = flags
    if counters is not None:
        f = flags.numpy()
        key = "shadow_free_entries"
        counters[key] = counters.get(key, 0) + int(np.count_nonzero(f.reshape(num_entries, -1).any(axis=1)))


def with_shadow_free(prepared: Callable[[], tuple[Shading, wp.array | None]], geo: Geometry, num_entries: int,
                     device: str, counters: dict | None = None) -> Callable[[], Shading]:
    """A callable giving the Shading of prepared() (Shading, occupancy table), with its
    shadow-free flags set for geo's entries the first time it is called."""
    done: list[Shading] = []
    lock = threading.Lock()

    def get() -> Shading:
        with lock:
            if not done:
                sh, occ = prepared()
                flag_shadow_free(sh, occ, geo, num_entries, device, counters)
                done.append(sh)
        return done[0]
    return get
