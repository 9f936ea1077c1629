"""Implicit gprims' tessellations kept on disk between processes, beside Warp's kernel cache.

trimesh makes the triangles of spheres, cylinders, cones and capsules (tessellate.py), but
importing it costs 0.5-0.9 s (it brings in scipy.spatial), more than a small frame: every
`warp-blur render` of a stage with a sphere paid it, once per process. The arrays it made are
kept as .npz files in `<Warp's kernel cache>/warp_blur_shapes/`, named by a hash of what made
them (the shape's kind and dimensions, trimesh's version and tessellate.py's own source), so a
later process loads them (~1 ms) without importing trimesh, and any change to either makes new
ones. An empty cache (WARP_CACHE_PATH at a new folder) costs the import again, as it costs the
kernels' compilation; an unreadable, damaged or unwritable cache only costs the import.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.metadata
import os
import tempfile
import zipfile
from typing import Callable

import numpy as np

from ..core import warp_setup  # noqa: F401  (Warp's settings, before anything starts it)

FOLDER = "warp_blur_shapes"


@functools.lru_cache(maxsize=1)
def _folder() -> str | None:
    """The cache folder (None: no disk cache, Warp has no kernel cache folder)."""
    import warp as wp
    wp.init()
    root = wp.config.kernel_cache_dir
    return os.path.join(root, FOLDER) if root else None


@functools.lru_cache(maxsize=1)
def _maker_stamp() -> str:
    """What the arrays depend on besides the key: trimesh's version and tessellate.py's source."""
    try:
        version = importlib.metadata.version("trimesh")
    except importlib.metadata.PackageNotFoundError:
        version = "?"
    with open(os.path.join(os.path.dirname(__file__), "tessellate.py"), "rb") as f:
        source = hashlib.sha256(f.read()).hexdigest()
    return f"trimesh {version} tessellate {source}"


def _path(key: str) -> str | None:
    folder = _folder()
    if folder is None:
        return None
    digest = hashlib.sha256(f"{_maker_stamp()}\n{key}".encode()).hexdigest()[:32]
    return os.path.join(folder, f"{digest}.npz")


def cached_arrays(key: str, make: Callable[[], tuple[np.ndarray, ...]]) -> tuple[np.ndarray, ...]:
    """make()'s arrays, from the disk cache when an earlier process made them for `key` (a text
    naming everything they depend on besides trimesh and tessellate.py), else made now and
    stored (written to a temporary name, then renamed: concurrent processes never read half a
    file)."""
    path = _path(key)
    if path is not None:
        try:
            with np.load(path, allow_pickle=False) as z:
                return tuple(z[f"a{i}"] for i in range(len(z.files)))
        except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile):
            pass   # not there yet, or damaged: made again below
    arrays = tuple(np.asarray(a) for a in make())
    if path is not None:
        try:
            os.makedirs(os.path.dirname(path), exist_ok=True)
            fd, tmp = tempfile.mkstemp(suffix=".npz.tmp", dir=os.path.dirname(path))
            try:
                with os.fdopen(fd, "wb") as f:
                    np.savez(f, **{f"a{i}": a for i, a in enumerate(arrays)})
                os.replace(tmp, path)
            except BaseException:
                os.unlink(tmp)
                raise
        except OSError:
            pass   # a read-only cache: the arrays are still right, only not kept
    return arrays
