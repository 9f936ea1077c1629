"""UsdUVTexture images into one texel atlas with mip levels, for the kernels' filtered lookups.

Images are read through USD's asset resolver (so files inside a `.usdz` package are found as
USD finds them) and decoded by Pillow (OpenEXR files by OpenEXR and Radiance `.hdr` by rgbe.py:
linear, as stored); 8-bit colour channels in sRGB (`sourceColorSpace` sRGB,
or `auto` for an 8-bit image) are made linear before filtering, alpha stays linear. Each texture
keeps a box-filtered mip chain down to 1×1. A texture that cannot be read falls back to the
node's `fallback` value with a warning (USD's rule).

Device layout (texture_lookup.py reads it): texels (N,) vec4 linear RGBA, all levels of all
textures one after another; levels (NLev, 3) int [offset, width, height]; textures (NT, 4) int
[first level, level count, wrapS, wrapT]; bindings (NB, BINDING_WIDTH) float [texture, output
channel (0 rgb, 1 r, 2 g, 3 b, 4 a), scale rgba, bias rgba, UDIM flag, texture-coordinate
transform (a UsdTransform2d: st' = M st + t as m00 m01 m10 m11 tx ty), log2 of its scale]. A UDIM binding's texture
is the first of 100 consecutive textures, tiles 1001..1100 (tile 1001 + u + 10 v), a missing tile
a 1×1 texture of the node's fallback.
"""

from __future__ import annotations

import io
import os
import threading
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..core.log import warn_once
from .rgbe import is_rgbe, read_rgbe

WRAP = {"repeat": 0, "mirror": 1, "clamp": 2, "black": 3, "useMetadata": 0}
CHANNEL = {"rgb": 0, "r": 1, "g": 2, "b": 3, "a": 4}
BINDING_WIDTH = 18
IDENTITY_ST = (1.0, 0.0, 0.0, 1.0, 0.0, 0.0)
UDIM_TILES = 100        # tiles 1001..1100: 10 across, 10 up
MAX_TEXTURE_SIDE = 8192

_image_cache: dict[tuple, list[np.ndarray] | None] = {}
#: why an image in _image_cache (None there) could not be read: said again by every Renderer that
#: reads it (warnings are said once per Renderer, core/log.py; the cache is the process's)
_image_errors: dict[tuple, str] = {}
_cache_lock = threading.Lock()


def srgb_to_linear(c: np.ndarray) -> np.ndarray:
    """The sRGB transfer function inverted (IEC 61966-2-1), elementwise on [0, 1]."""
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def mip_chain(img: np.ndarray) -> list[np.ndarray]:
    """(H, W, 4) float32 -> levels down to 1×1, each a 2×2 box filter of the one above (odd
    sides keep their last row or column)."""
    levels = [img]
    while max(img.shape[:2]) > 1:
        h, w = img.shape[:2]
        if h > 1:
            img = img[:h - h % 2]
            img = 0.5 * (img[0::2] + img[1::2])
        if w > 1:
            img = img[:, :w - w % 2]
            img = 0.5 * (img[:, 0::2] + img[:, 1::2])
        levels.append(img.astype(np.float32))
    return levels


def read_image(resolved_path: str, color_space: str) -> list[np.ndarray] | None:
    """Mip chain of (H, W, 4) linear float32 RGBA levels of an image asset, or None (unreadable).
    Cached per process by path, colour space and the file's (or package's) size and mtime."""
    return read_image_keyed(resolved_path, color_space)[1]


def file_stamp(resolved_path: str) -> tuple[int, int] | None:
    """(size, mtime in ns) of an image file (of the package a `pkg.usdz[inner]` path reads from),
    None when it cannot be read: a rewritten file gets a new stamp."""
    try:
        st = os.stat(resolved_path.split("[", 1)[0])
        return st.st_size, st.st_mtime_ns
    except OSError:
        return None


def read_image_keyed(resolved_path: str, color_space: str) -> tuple[tuple, list[np.ndarray] | None]:
    """(cache key, read_image's result): the key (path, colour space, size and mtime) names the
    texels exactly, so a frame's texel atlas can be matched to an earlier frame's upload."""
    key = (resolved_path, color_space, file_stamp(resolved_path))
    with _cache_lock:
        cached = key in _image_cache
        levels, error = _image_cache.get(key), _image_errors.get(key)
    if cached:
        if error is not None:
            warn_once(f"texture:{resolved_path}", error)
        return key, levels
    levels = None
    try:
        from PIL import Image
        from pxr import Ar
        asset = Ar.GetResolver().OpenAsset(Ar.ResolvedPath(resolved_path))
        if asset is None:
            raise OSError("not found")
        data = bytes(asset.GetBuffer())
        if data[:4] == EXR_MAGIC:       # OpenEXR (HDR dome maps, float textures): linear already
            rgba, eight_bit = _exr_rgba(data), False
        elif is_rgbe(data):             # Radiance .hdr: linear
            rgba, eight_bit = _shrunk(read_rgbe(data)), False
        else:
            with Image.open(io.BytesIO(data)) as im:
                if max(im.size) > MAX_TEXTURE_SIDE:
                    im.thumbnail((MAX_TEXTURE_SIDE, MAX_TEXTURE_SIDE))
                eight_bit = im.mode in ("L", "LA", "RGB", "RGBA", "P", "1")
                rgba = np.asarray(im.convert("RGBA"), np.float32) / 255.0 if eight_bit else _float_rgba(im)
        srgb = color_space == "sRGB" or (color_space == "auto" and eight_bit)
        if srgb:
            rgba[..., :3] = srgb_to_linear(rgba[..., :3])
        levels = mip_chain(np.ascontiguousarray(rgba, np.float32))
    except Exception as exc:   # any unreadable image: USD renders the fallback
        error = (f"texture {resolved_path} cannot be read ({type(exc).__name__}: {str(exc)[:80]}); "
                 f"using the node's fallback")
        warn_once(f"texture:{resolved_path}", error)
        with _cache_lock:
            _image_errors[key] = error
    with _cache_lock:
        _image_cache[key] = levels
    return key, levels


EXR_MAGIC = b"\x76\x2f\x31\x01"


def _exr_rgba(data: bytes) -> np.ndarray:
    """(H, W, 4) float32 RGBA of an OpenEXR image in memory (its first part): RGB(A), or Y as grey;
    alpha 1 when absent; NaN made 0 and infinities the largest half float; larger than
    MAX_TEXTURE_SIDE, box-reduced by a whole factor."""
    import OpenEXR
    with OpenEXR.File(io.BytesIO(data)) as f:
        channels = {k: np.asarray(v.pixels, np.float32) for k, v in f.channels().items()}
    if "RGBA" in channels:
        rgba = channels["RGBA"]
    elif "RGB" in channels:
        rgb = channels["RGB"]
        rgba = np.concatenate([rgb, np.ones(rgb.shape[:2] + (1,), np.float32)], axis=2)
    else:
        grey = channels.get("Y", channels.get("R", next(iter(channels.values()))))
        grey = grey if grey.ndim == 2 else grey[..., 0]
        rgba = np.stack([grey, grey, grey, channels.get("A", np.ones_like(grey))], axis=2)
    rgba = np.nan_to_num(rgba, nan=0.0, posinf=65504.0, neginf=-65504.0)
    return _shrunk(rgba)


def _shrunk(rgba: np.ndarray) -> np.ndarray:
    """(H, W, 4) float32 box-reduced by a whole factor until no side exceeds MAX_TEXTURE_SIDE."""
    factor = int(np.ceil(max(rgba.shape[:2]) / MAX_TEXTURE_SIDE))
    if factor > 1:
        h, w = (rgba.shape[0] // factor) * factor, (rgba.shape[1] // factor) * factor
        rgba = rgba[:h, :w].reshape(h // factor, factor, w // factor, factor, 4).mean(axis=(1, 3))
    return np.ascontiguousarray(rgba, np.float32)


def _float_rgba(im) -> np.ndarray:
    """RGBA float32 of a 16-bit or float image (I;16, I, F modes): grey replicated, alpha 1."""
    a = np.asarray(im, np.float32)
    if im.mode.startswith("I;16") or im.mode == "I":
        a = a / 65535.0
    if a.ndim == 2:
        a = np.repeat(a[..., None], 3, axis=2)
    if a.shape[2] == 3:
        a = np.concatenate([a, np.ones(a.shape[:2] + (1,), np.float32)], axis=2)
    return a


@dataclass
class TextureSet:
    """The frame's textures and bindings (material inputs read from a texture), as host arrays."""

    texels: list = field(default_factory=list)        # (n, 4) blocks
    levels: list = field(default_factory=list)        # [offset, w, h]
    textures: list = field(default_factory=list)      # [first level, count, wrapS, wrapT]
    bindings: list = field(default_factory=list)      # BINDING_WIDTH floats
    sources: list = field(default_factory=list)       # what each texture's texels were read from
    _texture_index: dict = field(default_factory=dict)
    _binding_index: dict = field(default_factory=dict)   # row -> its index: equal rows are one binding
    _read: list = field(default_factory=list)            # (path, stamp) of every image file read or tried
    _udim_sets: list = field(default_factory=list)       # (find, tiles found) of every UDIM set looked up
    _size: int = 0
    device_arrays: dict = field(default_factory=dict)   # device -> uploaded arrays

    def add_texture(self, resolved_path: str, color_space: str, wrap_s: str, wrap_t: str) -> tuple[int, int] | None:
        """(texture index, level-0 size in texels) of an image with these wrap modes, or None."""
        key = (resolved_path, color_space, wrap_s, wrap_t)
        if key not in self._texture_index:
            source, chain = read_image_keyed(resolved_path, color_space)
            self._read.append((resolved_path, source[2]))
            if chain is None:
                self._texture_index[key] = None
            else:
                self._texture_index[key] = (self._append(chain, wrap_s, wrap_t, source), max(chain[0].shape[:2]))
        return self._texture_index[key]

    def _append(self, chain: list[np.ndarray], wrap_s: str, wrap_t: str, source: tuple) -> int:
        self.device_arrays.clear()   # uploaded before this texture: stale (a table kept across frames)
        first = len(self.levels)
        self.sources.append(source)
        for lev in chain:
            h, w = lev.shape[:2]
            self.levels.append([self._size, w, h])
            self.texels.append(lev.reshape(-1, 4))
            self._size += w * h
        self.textures.append([first, len(chain), WRAP.get(wrap_s, 0), WRAP.get(wrap_t, 0)])
        return len(self.textures) - 1

    def add_udim(self, tiles: list[tuple[str, int]], color_space: str, fallback) -> int | None:
        """The first of UDIM_TILES consecutive textures of a UDIM set ((resolved path, tile id)
        pairs; tiles that are missing or unreadable hold `fallback` rgba), or None when no tile reads."""
        chains = {}
        sources = {}
        for path, tile in tiles:
            if 1001 <= tile < 1001 + UDIM_TILES:
                source, chain = read_image_keyed(path, color_space)
                self._read.append((path, source[2]))
                if chain is not None:
                    chains[tile] = chain
                    sources[tile] = source
        if not chains:
            return None
        blank = [np.asarray(fallback, np.float32).reshape(1, 1, 4)]
        blank_source = ("fallback", tuple(float(x) for x in blank[0].ravel()))
        base = len(self.textures)
        for tile in range(1001, 1001 + UDIM_TILES):
            source = sources.get(tile, blank_source)
            self._append(chains.get(tile, blank), "clamp", "clamp", source)
        return base

    def same_sample(self, a: int, b: int) -> bool:
        """True when bindings a and b (-1: none) read the same texture the same way (UDIM flag,
        coordinate transform, level bias): their samples are equal everywhere, only scale, bias
        and channel may differ."""
        if a < 0 or b < 0:
            return False
        ra, rb = self.bindings[a], self.bindings[b]
        return ra[0] == rb[0] and ra[10:18] == rb[10:18]

    def add_binding(self, texture: int, channel: str, scale, bias, udim: bool = False,
                    st_transform=IDENTITY_ST) -> int:
        """A binding row; st_transform (m00, m01, m10, m11, tx, ty) maps the surface's texture
        coordinates before the lookup (its area scale moves the mip level)."""
        m = np.asarray(st_transform, np.float64)
        area = abs(m[0] * m[3] - m[1] * m[2])
        row = [float(texture), float(CHANNEL.get(channel, 0)), *map(float, scale), *map(float, bias),
               1.0 if udim else 0.0, *map(float, m), 0.5 * float(np.log2(max(area, 1e-30)))]
        # an equal row is the same binding (a table kept across frames adds its dome's again)
        key = tuple(row)
        if key not in self._binding_index:
            self._binding_index[key] = len(self.bindings)
            self.bindings.append(row)
            self.device_arrays.clear()
        return self._binding_index[key]

    def note_udim_set(self, find: Callable[[], list], found: list) -> None:
        """Remember a UDIM set's tile lookup (find() -> [(resolved path, tile id)]) and the tiles
        it found, so that files_changed notices a tile added (or removed) beside them."""
        self._udim_sets.append((find, frozenset(found)))

    def files_changed(self) -> bool:
        """True when an image file read into the set, or tried and not found, has been written
        (or removed) since, or a UDIM set looked up now finds other tiles (one added beside those
        found): a set kept across frames (material_cache.py) is then read again."""
        return (any(stamp != file_stamp(path) for path, stamp in self._read)
                or any(frozenset(find()) != found for find, found in self._udim_sets))

    @property
    def empty(self) -> bool:
        return not self.bindings

    @property
    def texel_key(self) -> tuple:
        """What the texel atlas holds, in order (each image by read_image's cache key: path, colour
        space, the file's size and mtime; or a fallback's value): equal keys, equal texels, so a
        frame that reads the same images as an earlier one reuses its upload (device_data)."""
        return tuple(self.sources)

    def texel_atlas(self) -> np.ndarray:
        """(N, 4) float32: every level of every texture, one after another (one row at least)."""
        return np.concatenate(self.texels).astype(np.float32) if self.texels else np.zeros((1, 4), np.float32)

    def index_arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(levels (L, 3) i32, textures (T, 4) i32, bindings (B, W) f32), at least one row each
        (kernels take no empty arrays)."""
        levels = np.asarray(self.levels or [[0, 1, 1]], np.int32)
        textures = np.asarray(self.textures or [[0, 1, 0, 0]], np.int32)
        bindings = np.asarray(self.bindings or [[0.0] * BINDING_WIDTH], np.float32)
        return levels, textures, bindings


def texture_lod(proj, positions: np.ndarray, tri_vertices: np.ndarray, corner_uvs: np.ndarray) -> np.ndarray:
    """(T,) float32 log2 of each triangle's texture-coordinate span per pixel at the shutter
    centre: 0.5 log2(uv area / pixel area), so a texture of side S is read at mip level
    lod + log2(S) (-30 where the triangle has no screen area: full resolution).

    positions: (V, 3) camera space; tri_vertices: (T, 3); corner_uvs: (3T, 2)."""
    px = proj.project(positions)[tri_vertices]                   # (T, 3, 2) pixels
    uv = corner_uvs.reshape(-1, 3, 2).astype(np.float64)
    def area(p):
        return 0.5 * np.abs((p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1])
                            - (p[:, 2, 0] - p[:, 0, 0]) * (p[:, 1, 1] - p[:, 0, 1]))
    with np.errstate(all="ignore"):
        ratio = area(uv) / area(px)
        lod = 0.5 * np.log2(ratio)
    lod[~np.isfinite(lod)] = -30.0
    return lod.astype(np.float32)
