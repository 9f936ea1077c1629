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

#: re-entrant: a collection inside reused_empty's critical section may run _keep in the same thread
_lock = threading.RLock()
_kept: list[tuple[tuple, wp.array]] = []


def reused_empty(shape: tuple[int, ...], dtype) -> wp.array:
    """An uninitialised host array like wp.empty(shape, dtype, device="cpu"), made of a kept
    array's memory when one of that shape and type is free. The memory is kept again only once
    the returned array is collected, and every reader holds it (a Shading struct, a view made
    from it, a NumPy view of it): it is a view of the kept array, so a frame's maps are never
    handed on while a pass still reads them."""
    key = (tuple(int(n) for n in shape), dtype)
    backing = None
    with _lock:
        for i in range(len(_kept) - 1, -1, -1):
            if _kept[i][0] == key:
                backing = _kept.pop(i)[1]
                break
    if backing is None:
        backing = wp.empty(key[0], dtype=dtype, device="cpu")
    array = wp.array(ptr=backing.ptr, shape=backing.shape, strides=backing.strides, dtype=dtype, device="cpu")
    weakref.finalize(array, _keep, key, backing)
    return array


def _keep(key: tuple, array: wp.array) -> None:
    with _lock:
        _kept.append((key, array))
        del _kept[:-MAX_KEPT]


def clear() -> None:
    """Drop every kept array (their memory goes back to the system)."""
    with _lock:
        _kept.clear()
