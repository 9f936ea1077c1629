"""Converged references for benchmarks: accumulation at many instants, cached under bench/out/refs
and reused while the scene file, the resolution, the frame and warp_blur's own code are unchanged."""

from __future__ import annotations

import glob
import hashlib
import os

import numpy as np

import warp_blur as wb
from warp_blur.output.files import read_exr, write_exr

from common import OUT, ROOT


def code_hash() -> str:
    h = hashlib.sha256()
    for path in sorted(glob.glob(os.path.join(ROOT, "warp_blur", "**", "*.py"), recursive=True)):
        with open(path, "rb") as f:
            h.update(f.read())
    return h.hexdigest()[:12]


def reference(scene: str, frame: float, resolution: tuple[int, int], samples: int) -> np.ndarray:
    """(H, W, 4) accumulation reference at `samples` instants (cached EXR)."""
    with open(scene, "rb") as f:
        scene_hash = hashlib.sha256(f.read()).hexdigest()[:12]
    name = f"{os.path.basename(scene)[:-5]}_f{frame:g}_{resolution[0]}x{resolution[1]}_n{samples}_{scene_hash}_{code_hash()}.exr"
    path = os.path.join(OUT, "refs", name)
    if os.path.exists(path):
        return read_exr(path)["RGBA"]
    result = wb.render(scene, frame=frame, resolution=resolution, method="accumulation", samples=samples, aovs=())
    write_exr(path, result)
    return result.rgba
