"""Tile lists from entry boxes and swept slabs, as Warp kernels on the host (binning.bin_entries).

The pair work (every tile an entry's box reaches, each tested against the entry's slabs) was
NumPy's, one temporary array per step over all pairs: on `large` at 1024x768 the moving entries'
lists took 23 ms a frame (48 ms with 8-pixel tiles), and accumulation bins once per instant.
Here one kernel counts each entry's tiles, a second writes them, and a third scatters the entries
into their tiles' lists in a given entry order, so each list holds its entries in that order
(the caller's order key, then entry index) — the lists NumPy's stable sort made, the same pairs:
the slab test is the same float64 arithmetic as the NumPy form tests/test_binning.py keeps.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ..core.parallel import cheap_pass_threads, launch_pixels

#: slack (pixels) the slab test keeps on the sample kernels' side of float32 rounding (box_rejects)
SLAB_SLACK = wp.constant(wp.float64(1.0e-3))


@wp.func
def tile_range(boxes: wp.array2d(dtype=wp.float64), e: int, tile_size: int, tiles_x: int, tiles_y: int) -> wp.vec4i:
    """(tx0, ty0, tx1, ty1), inclusive: the tiles entry e's pixel box reaches, clamped to the screen."""
    ts = wp.float64(tile_size)
    tx0 = wp.clamp(wp.floor(boxes[e, 0] / ts), wp.float64(0.0), wp.float64(tiles_x - 1))
    ty0 = wp.clamp(wp.floor(boxes[e, 1] / ts), wp.float64(0.0), wp.float64(tiles_y - 1))
    tx1 = wp.clamp(wp.floor(boxes[e, 2] / ts), wp.float64(0.0), wp.float64(tiles_x - 1))
    ty1 = wp.clamp(wp.floor(boxes[e, 3] / ts), wp.float64(0.0), wp.float64(tiles_y - 1))
    return wp.vec4i(int(tx0), int(ty0), int(tx1), int(ty1))


@wp.func
def slabs_reach(bands: wp.array3d(dtype=wp.float32), e: int, tx: int, ty: int, tile_size: int) -> bool:
    """False when one of entry e's slabs (nx, ny, lo, hi) misses tile (tx, ty) altogether: no sample
    of the tile passes the kernels' slab test (box_rejects), so the pair need not be listed. The
    tile's range along the slab's normal is its centre's ± half its extent."""
    half = wp.float64(0.5) * wp.float64(tile_size)
    for k in range(bands.shape[1]):
        nx = wp.float64(bands[e, k, 0])
        ny = wp.float64(bands[e, k, 1])
        centre = nx * (wp.float64(tx * tile_size) + half) + ny * (wp.float64(ty * tile_size) + half)
        reach = (wp.abs(nx) + wp.abs(ny)) * half + SLAB_SLACK
        if centre + reach < wp.float64(bands[e, k, 2]) or centre - reach > wp.float64(bands[e, k, 3]):
            return False
    return True


@wp.kernel(enable_backward=False)
def count_entry_tiles(order: wp.array(dtype=int), boxes: wp.array2d(dtype=wp.float64),
                      bands: wp.array3d(dtype=wp.float32), tile_size: int, tiles_x: int, tiles_y: int,
                      first: int,
                      # output
                      counts: wp.array(dtype=int)):
    """counts[i]: how many tiles list entry order[i] (its box's tiles its slabs reach), for
    i = first + tid (launched over bands of entries)."""
    i = first + wp.tid()
    e = order[i]
    r = tile_range(boxes, e, tile_size, tiles_x, tiles_y)
    n = int(0)
    for ty in range(r[1], r[3] + 1):
        for tx in range(r[0], r[2] + 1):
            if slabs_reach(bands, e, tx, ty, tile_size):
                n += 1
    counts[i] = n


@wp.kernel(enable_backward=False)
def write_entry_tiles(order: wp.array(dtype=int), boxes: wp.array2d(dtype=wp.float64),
                      bands: wp.array3d(dtype=wp.float32), tile_size: int, tiles_x: int, tiles_y: int,
                      starts: wp.array(dtype=int), first: int,
                      # output
                      pair_tiles: wp.array(dtype=int)):
    """pair_tiles[starts[i]:starts[i + 1]]: the tiles that list entry order[i], row by row, for
    i = first + tid (launched over bands of entries)."""
    i = first + wp.tid()
    e = order[i]
    r = tile_range(boxes, e, tile_size, tiles_x, tiles_y)
    k = starts[i]
    for ty in range(r[1], r[3] + 1):
        for tx in range(r[0], r[2] + 1):
            if slabs_reach(bands, e, tx, ty, tile_size):
                pair_tiles[k] = ty * tiles_x + tx
                k += 1


@wp.kernel(enable_backward=False)
def scatter_by_tile(order: wp.array(dtype=int), starts: wp.array(dtype=int), pair_tiles: wp.array(dtype=int),
                    num_entries: int,
                    # in: each tile's first slot; out: its end
                    cursor: wp.array(dtype=int),
                    # output
                    tile_entries: wp.array(dtype=int)):
    """One thread: the entries, in `order`, appended to the lists of their tiles (a stable
    counting sort of the pairs by tile)."""
    for i in range(num_entries):
        e = order[i]
        for k in range(starts[i], starts[i + 1]):
            t = pair_tiles[k]
            tile_entries[cursor[t]] = e
            cursor[t] = cursor[t] + 1


def tile_lists(boxes: np.ndarray, order: np.ndarray, bands: np.ndarray, tile_size: int, tiles_x: int,
               tiles_y: int) -> tuple[np.ndarray, np.ndarray]:
    """(tile_offsets (tiles + 1,) int32, tile_entries (pairs,) int32): each tile's entries among
    `order` (entry indices, in the order each list is to hold them) whose box (boxes (E, 4)
    float64 pixels) reaches the tile and whose slabs (bands (E, S, 4) float32) do not miss it."""
    n = len(order)
    num_tiles = tiles_x * tiles_y
    if n == 0:
        return np.zeros(num_tiles + 1, np.int32), np.zeros(0, np.int32)
    dev = "cpu"
    # host arrays read in place (no copy of every entry's box and slabs for a few listed ones)
    order_np = np.ascontiguousarray(order, np.int32)
    boxes_np = np.ascontiguousarray(boxes, np.float64)
    bands_np = np.ascontiguousarray(bands, np.float32)
    order_w = wp.array(order_np, dtype=int, device=dev, copy=False)
    boxes_w = wp.array(boxes_np, dtype=wp.float64, device=dev, copy=False)
    bands_w = wp.array(bands_np, dtype=wp.float32, device=dev, copy=False)
    counts = wp.empty(n, dtype=int, device=dev)
    # (each entry writes only its own count and pairs: bands of entries run on every core, and a
    # few thousand entries, as an accumulation instant bins, in one launch)
    threads = cheap_pass_threads(n, None)
    launch_pixels(count_entry_tiles, n,
                  lambda first, _n: [order_w, boxes_w, bands_w, tile_size, tiles_x, tiles_y, first, counts], dev,
                  threads)
    starts_np = np.zeros(n + 1, np.int64)
    np.cumsum(counts.numpy(), out=starts_np[1:])
    total = int(starts_np[-1])
    if total >= 2**31:
        raise MemoryError(f"{total} tile-list pairs do not fit 32-bit indices")
    starts32 = starts_np.astype(np.int32)   # kept alive here: the Warp array reads it in place
    starts = wp.array(starts32, dtype=int, device=dev, copy=False)
    pair_tiles = wp.empty(max(total, 1), dtype=int, device=dev)
    launch_pixels(write_entry_tiles, n,
                  lambda first, _n: [order_w, boxes_w, bands_w, tile_size, tiles_x, tiles_y, starts, first,
                                     pair_tiles], dev, threads)
    per_tile = np.bincount(pair_tiles.numpy()[:total], minlength=num_tiles)
    offsets = np.zeros(num_tiles + 1, np.int64)
    np.cumsum(per_tile, out=offsets[1:])
    cursor_np = offsets[:-1].astype(np.int32)
    cursor = wp.array(cursor_np, dtype=int, device=dev, copy=False)
    entries = wp.empty(max(total, 1), dtype=int, device=dev)
    wp.launch(scatter_by_tile, dim=1, inputs=[order_w, starts, pair_tiles, n, cursor], outputs=[entries], device=dev)
    return offsets.astype(np.int32), entries.numpy()[:total].astype(np.int32)
