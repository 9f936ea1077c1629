"""Freed memory kept for the next frame (glibc's malloc), so frames stop paying page faults.

glibc gives every allocation over its mmap threshold (at most 32 MB by default) pages of its own
and returns them to the system on free; the heap's free top is returned too once it exceeds the
trim threshold. A frame allocates hundreds of MB of short-lived buffers (analytic's interval
arrays, per-band scratch, NumPy temporaries), so each frame faulted them in again: about 93,000
page faults and 0.35 s of system time per `large` analytic frame at 1024x768 on 2 cores. With
both thresholds raised, freed buffers stay mapped in the heap and the next frame reuses them: the
process's peak memory is about what the frame needs anyway (0.77 -> 0.93 GB on `large`), held
until exit. Process-wide, so it is applied once, when Warp is initialised for rendering;
WARP_BLUR_KEEP_FREED_MEMORY=0 leaves malloc as it was. Other C libraries: nothing is done.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import sys

#: mallopt parameters (malloc.h)
M_TRIM_THRESHOLD = -1
M_MMAP_THRESHOLD = -3
#: buffers up to this size come from the heap and stay there when freed
KEEP_BYTES = 1 << 30
#: glibc versions that cap the mmap threshold accept at most this (HEAP_MAX_SIZE / 2 on 64 bits)
CAPPED_MMAP_THRESHOLD = 32 << 20

_applied: bool | None = None


def keep_freed_memory() -> bool:
    """Raise glibc's mmap and trim thresholds once per process (see the module docstring); True
    when they are raised (now or before), False where switched off or not glibc."""
    global _applied
    if _applied is not None:
        return _applied
    _applied = False
    if os.environ.get("WARP_BLUR_KEEP_FREED_MEMORY", "1") == "0" or not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        mallopt = libc.mallopt
    except (OSError, AttributeError):   # not glibc (musl has no mallopt)
        return False
    mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
    mallopt.restype = ctypes.c_int
    if not mallopt(M_MMAP_THRESHOLD, KEEP_BYTES) and not mallopt(M_MMAP_THRESHOLD, CAPPED_MMAP_THRESHOLD):
        return False
    _applied = bool(mallopt(M_TRIM_THRESHOLD, KEEP_BYTES))
    return _applied
