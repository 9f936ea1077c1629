"""Large host arrays handed from one frame to the next.

Memory a process touches for the first time costs the kernel a page fault and a page of zeroes
per 4 KiB: about 1 ms per 4 MB here, worse when two threads fault at once. A frame's shadow maps
(50 MB for demo's six faces at 8 instants) would pay that again every frame; kept, the next
frame's maps of the same shape write into memory that is already mapped.
"""

from __future__ import annotations

import threading
import weakref

import warp as wp

#: arrays kept for reuse, most recent last (a frame needs one; a second covers two renderers)
MAX_KEPT = 2

_lock = threading.Lock()
_kept: list[tuple[tuple, wp.array]] = []


def reused_empty(shape: tuple[int, ...], dtype, holder: object) -> wp.array:
    """An uninitialised host array like wp.empty(shape, dtype, device="cpu"), made of a kept
    array's memory when one of that shape and type is free. It is kept again once `holder` (the
    object that owns it and outlives every reader of it) is collected."""
    key = (tuple(int(n) for n in shape), dtype)
    array = None
    with _lock:
        for i in range(len(_kept) - 1, -1, -1):
            if _kept[i][0] == key:
                array = _kept.pop(i)[1]
                break
    if array is None:
        array = wp.empty(key[0], dtype=dtype, device="cpu")
    weakref.finalize(holder, _keep, key, array)
    return array


def _keep(key: tuple, array: wp.array) -> None:
    with _lock:
        _kept.append((key, array))
        del _kept[:-MAX_KEPT]


def clear() -> None:
    """Drop every kept array (their memory goes back to the system)."""
    with _lock:
        _kept.clear()
