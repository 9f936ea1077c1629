"""Writing frames: float EXR (RGBA + AOVs + metadata header) and 8-bit sRGB PNG previews, both
written to a temporary name in the target folder and renamed when whole (never a partial file)."""

from __future__ import annotations

import json
import os
import tempfile

import numpy as np
import OpenEXR
from PIL import Image

from .errors import UserError

COMPRESSIONS = {
    "zip": OpenEXR.ZIP_COMPRESSION, "zips": OpenEXR.ZIPS_COMPRESSION, "piz": OpenEXR.PIZ_COMPRESSION,
    "none": OpenEXR.NO_COMPRESSION, "rle": OpenEXR.RLE_COMPRESSION, "dwaa": OpenEXR.DWAA_COMPRESSION,
}


def _check_target(path: str) -> str:
    folder = os.path.dirname(os.path.abspath(path))
    probe = folder
    while probe and not os.path.exists(probe):
        probe = os.path.dirname(probe)
    if probe and not os.path.isdir(probe):
        raise UserError(f"cannot write {path}: {probe} is a file, not a folder")
    try:
        os.makedirs(folder, exist_ok=True)
    except OSError as exc:
        raise UserError(f"cannot create output folder {folder}: {exc.strerror}") from None
    return folder


def _atomic(path: str, write) -> None:
    folder = _check_target(path)
    fd, tmp = tempfile.mkstemp(prefix=".tmp-", suffix=os.path.splitext(path)[1], dir=folder)
    os.close(fd)
    try:
        write(tmp)
        os.replace(tmp, path)
    except OSError as exc:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise UserError(f"cannot write {path}: {exc.strerror or exc}") from None
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def exr_channels(result) -> dict[str, np.ndarray]:
    """EXR channels of a result: RGBA, and AOVs Z, motion.X/motion.Y, coverage."""
    ch = {"RGBA": np.ascontiguousarray(result.rgba, np.float32)}
    if "Z" in result.aovs:
        ch["Z"] = np.ascontiguousarray(result.aovs["Z"], np.float32)
    if "motion" in result.aovs:
        ch["motion.X"] = np.ascontiguousarray(result.aovs["motion"][..., 0], np.float32)
        ch["motion.Y"] = np.ascontiguousarray(result.aovs["motion"][..., 1], np.float32)
    if "coverage" in result.aovs:
        ch["coverage"] = np.ascontiguousarray(result.aovs["coverage"], np.float32)
    return ch


def write_exr(path: str, result, compression: str = "zip", extra_header: dict | None = None) -> None:
    """Write a result as a float32 EXR with its metadata in the header (atomic)."""
    header = {"compression": COMPRESSIONS[compression], "type": OpenEXR.scanlineimage}
    for k, v in (getattr(result, "metadata", None) or {}).items():
        header[f"warp_blur.{k}"] = v if isinstance(v, str) else json.dumps(v)
    for k, v in (extra_header or {}).items():
        header[k] = v
    channels = exr_channels(result)

    def write(tmp: str) -> None:
        with OpenEXR.File(header, channels) as f:
            f.write(tmp)

    _atomic(path, write)


def write_png(path: str, rgba: np.ndarray) -> None:
    """8-bit sRGB preview of linear RGBA (alpha kept)."""
    c = np.clip(rgba, 0.0, 1.0)
    rgb = np.where(c[..., :3] <= 0.0031308, 12.92 * c[..., :3], 1.055 * np.power(c[..., :3], 1 / 2.4) - 0.055)
    out = np.concatenate([rgb, c[..., 3:4]], axis=-1)
    img = Image.fromarray((out * 255.0 + 0.5).astype(np.uint8), "RGBA")
    _atomic(path, lambda tmp: img.save(tmp, format="PNG"))


def write_image(path: str, result, compression: str = "zip") -> None:
    """Write by extension: .exr (float) or .png (preview)."""
    ext = os.path.splitext(path)[1].lower()
    if ext == ".exr":
        write_exr(path, result, compression)
    elif ext == ".png":
        write_png(path, result.rgba)
    else:
        raise UserError(f"output {path}: unsupported extension '{ext}' (use .exr or .png)")


def read_exr(path: str) -> dict[str, np.ndarray]:
    """Channels of an EXR: 'RGBA' (H, W, 4) when present, else separate channels; plus header."""
    if not os.path.exists(path):
        raise UserError(f"image not found: {path}")
    try:
        with OpenEXR.File(path, separate_channels=True) as f:
            chans = {k: np.asarray(v.pixels, np.float32) for k, v in f.channels().items()}
            header = dict(f.header())
    except Exception as exc:  # OpenEXR raises plain exceptions for unreadable files
        raise UserError(f"cannot read EXR {path}: {exc}") from None
    if all(c in chans for c in "RGBA"):
        chans["RGBA"] = np.stack([chans["R"], chans["G"], chans["B"], chans["A"]], axis=-1)
    elif all(c in chans for c in "RGB"):
        chans["RGBA"] = np.stack([chans["R"], chans["G"], chans["B"], np.ones_like(chans["R"])], axis=-1)
    chans["__header__"] = header
    return chans
