"""Compile (or load from Warp's kernel cache) the kernel modules a method will launch, several at
once, before its first frame: Warp otherwise builds each module when a pass first launches one of
its kernels, one after another. With an empty kernel cache that made demo's first accumulation
frame take ~15 s and the first analytic frame ~13 s more; two modules compile in 8 s side by side
against 13 s in turn. Which modules a method needs is the method's list (methods/__init__.py); a
module left off is still built when first launched, so the list costs time, never correctness.
"""

from __future__ import annotations

import importlib
import threading
from concurrent.futures import ThreadPoolExecutor
from typing import Sequence

import warp as wp

from . import progress
from .parallel import default_threads

#: tests switch this off to see which modules a method loads by itself
ENABLED = True

_loaded: set[tuple[str, str]] = set()
_lock = threading.Lock()


def preload_modules(names: Sequence[str], device: str, threads: int | None = None) -> None:
    """Load the Warp modules named (Python module names; the longest to build first) on device,
    `threads` at a time (every core by default); each (module, device) once per process."""
    if not ENABLED:
        return
    with _lock:
        todo = [n for n in names if (n, device) not in _loaded]
        _loaded.update((n, device) for n in todo)
    if not todo:
        return
    for name in todo:
        importlib.import_module(name)

    def load(name: str) -> None:
        wp.load_module(name, device=device)
        progress.band_done()
    progress.stage("kernels")   # a frame's bar shows the modules built (seconds each on an empty cache)
    progress.bands_started(len(todo))
    workers = max(1, min(len(todo), threads or default_threads()))
    with ThreadPoolExecutor(max_workers=workers, thread_name_prefix="warp_blur_preload") as pool:
        list(pool.map(load, todo))
