"""Writing frames: float EXR (RGBA + AOVs + metadata header) and 8-bit sRGB PNG previews, both
written to a temporary name in the target folder and renamed when whole (never a partial file)."""

from __future__ import annotations

import json
import os
import socket
import tempfile

import numpy as np
import OpenEXR
from PIL import Image

from ..core.errors import UserError

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


TEMP_PREFIX = ".tmp-warp_blur-"


def temporary_prefix() -> str:
    """Temporaries are named `.tmp-warp_blur-HOST-PID-…`: a later run removes only those whose
    owner (this host's process PID) is gone, never a live run's file (batch.remove_stale_temporaries)."""
    return f"{TEMP_PREFIX}{socket.gethostname().replace('-', '_')}-{os.getpid()}-"


def _umask_mode() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return 0o666 & ~mask


def check_writable(path: str) -> None:
    """Fail now (UserError) when the output's folder cannot be created or written to."""
    folder = _check_target(path)
    try:
        fd, probe = tempfile.mkstemp(prefix=temporary_prefix(), dir=folder)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise UserError(f"cannot write to the output folder {folder}: {exc.strerror or exc}") from None


def _atomic(path: str, write) -> None:
    folder = _check_target(path)
    fd, tmp = tempfile.mkstemp(prefix=temporary_prefix(), suffix=os.path.splitext(path)[1], dir=folder)
    os.close(fd)
    try:
        write(tmp)
        os.chmod(tmp, _umask_mode())   # mkstemp makes 0600: give the mode the user's umask gives
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
    header.update(getattr(result, "exr_attributes", None) or {})   # OpenEXR's standard attributes
    for k, v in (getattr(result, "metadata", None) or {}).items():
        header[f"warp_blur.{k}"] = v if isinstance(v, str) else json.dumps(v)
    for k, v in (extra_header or {}).items():
        header[k] = v
    channels = exr_channels(result)

    def write(tmp: str) -> None:
        with OpenEXR.File(header, channels) as f:
            f.write(tmp)

    _atomic(path, write)


def srgb_preview(rgba: np.ndarray) -> Image.Image:
    """Opaque 8-bit sRGB image of linear RGB: RGB already holds the background (dome or black),
    so the preview shows what the frame looks like; coverage stays in the EXR's alpha."""
    c = np.clip(rgba[..., :3], 0.0, 1.0)
    rgb = np.where(c <= 0.0031308, 12.92 * c, 1.055 * np.power(c, 1 / 2.4) - 0.055)
    return Image.fromarray((rgb * 255.0 + 0.5).astype(np.uint8), "RGB")


def write_png(path: str, rgba: np.ndarray, text: dict[str, str] | None = None) -> None:
    """8-bit sRGB preview of a linear RGBA frame, with optional text chunks (atomic)."""
    from PIL import PngImagePlugin
    img = srgb_preview(rgba)
    info = PngImagePlugin.PngInfo()
    for k, v in (text or {}).items():
        info.add_text(k, v)
    _atomic(path, lambda tmp: img.save(tmp, format="PNG", pnginfo=info))


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


def write_exr_channels(path: str, channels: dict[str, np.ndarray], header: dict | None = None) -> None:
    """Write arbitrary float channels (e.g. a difference image) atomically."""
    hdr = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage, **(header or {})}

    def write(tmp: str) -> None:
        with OpenEXR.File(hdr, {k: np.ascontiguousarray(v, np.float32) for k, v in channels.items()}) as f:
            f.write(tmp)

    _atomic(path, write)


def output_fingerprint_write(path: str, result, compression: str, fingerprint: str) -> None:
    """Write a frame carrying its settings fingerprint (EXR header / PNG text chunk) for --resume.
    A frame with a non-finite pixel is never written (an internal error, reported for the frame)."""
    aovs_ok = all(not np.isnan(a).any() if name == "Z" else np.isfinite(a).all()   # Z is +inf where nothing is seen
                  for name, a in result.aovs.items())
    if not np.isfinite(result.rgba).all() or not aovs_ok:
        raise RuntimeError(f"frame {result.metadata.get('frame')} has non-finite pixels; nothing written")
    if os.path.splitext(path)[1].lower() == ".exr":
        write_exr(path, result, compression, {"warp_blur.fingerprint": fingerprint})
    else:
        write_png(path, result.rgba, {"warp_blur.fingerprint": fingerprint})
