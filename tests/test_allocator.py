"""core/allocator.py: freed frame buffers stay mapped, so the next frame's buffers of the same
size cost no page faults (each case in a subprocess: the setting is process-wide)."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

PROBE = """
import resource, sys
import numpy as np
from warp_blur.core.allocator import keep_freed_memory
print(keep_freed_memory())
(getattr(np, "_core", None) or np.core).multiarray._set_madvise_hugepage(False)   # 4 KiB pages, whatever THP does
a = np.ones(16 << 20, np.float32)   # 64 MB: over glibc's default mmap threshold
del a
before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
b = np.ones(16 << 20, np.float32)
print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before)
"""


def _probe(keep: str) -> tuple[str, int]:
    env = {**os.environ, "WARP_BLUR_KEEP_FREED_MEMORY": keep}
    out = subprocess.run([sys.executable, "-c", PROBE], env=env, capture_output=True, text=True, check=True)
    applied, faults = out.stdout.split()
    return applied, int(faults)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's malloc only")
def test_freed_buffers_are_reused_without_page_faults():
    applied, faults = _probe("1")
    assert applied == "True"
    assert faults < 100            # 64 MB faulted in again would be 16384 pages of 4 KiB


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's malloc only")
def test_switched_off_leaves_malloc_as_it_was():
    applied, faults = _probe("0")
    assert applied == "False"
    assert faults > 8000           # the default: unmapped on free, its 16384 pages faulted in again
