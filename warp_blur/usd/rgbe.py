"""Radiance RGBE (`.hdr`) images, the other common format of HDR dome maps: Pillow and OpenEXR do
not read them, and no small, well-kept Python reader exists, so this decodes the format (Greg
Ward's `FORMAT=32-bit_rle_rgbe`: flat or per-channel run-length scanlines) into linear float RGB."""

from __future__ import annotations

import numpy as np

RGBE_MAGIC = (b"#?RADIANCE", b"#?RGBE")


def is_rgbe(data: bytes) -> bool:
    return data.startswith(RGBE_MAGIC)


def read_rgbe(data: bytes) -> np.ndarray:
    """(H, W, 4) float32 linear RGBA (alpha 1) of a Radiance HDR file's bytes, top row first.
    Raises ValueError on a malformed file."""
    pos = data.find(b"\n\n")
    if pos < 0:
        raise ValueError("no end of header")
    header = data[:pos].split(b"\n")
    if any(line.startswith(b"FORMAT=") and line.strip() != b"FORMAT=32-bit_rle_rgbe" for line in header):
        raise ValueError("only FORMAT=32-bit_rle_rgbe is read")
    end = data.find(b"\n", pos + 2)
    size = data[pos + 2:end].split()
    if len(size) != 4 or size[0][1:] != b"Y" or size[2][1:] != b"X":
        raise ValueError(f"unsupported resolution line {data[pos + 2:end][:40]!r}")
    h, w = int(size[1]), int(size[3])
    if not (0 < h <= 1 << 15 and 0 < w <= 1 << 15):
        raise ValueError("image size out of range")
    raw = np.frombuffer(data, np.uint8, offset=end + 1)
    rgbe = np.empty((h, w, 4), np.uint8)
    at = 0
    for y in range(h):
        new_rle = 8 <= w < 32768 and at + 4 <= len(raw) and raw[at] == 2 and raw[at + 1] == 2 \
            and (int(raw[at + 2]) << 8 | int(raw[at + 3])) == w
        if not new_rle:                 # flat scanline: W RGBE quadruples
            if at + 4 * w > len(raw):
                raise ValueError("truncated scanline")
            rgbe[y] = raw[at:at + 4 * w].reshape(w, 4)
            at += 4 * w
            continue
        at += 4
        for c in range(4):              # each channel run-length coded on its own
            x = 0
            while x < w:
                if at >= len(raw):
                    raise ValueError("truncated scanline")
                count = int(raw[at])
                if count > 128:         # a run of one byte
                    count -= 128
                    if x + count > w or at + 1 >= len(raw):
                        raise ValueError("bad run")
                    rgbe[y, x:x + count, c] = raw[at + 1]
                    at += 2
                else:                   # `count` literal bytes
                    if count == 0 or x + count > w or at + 1 + count > len(raw):
                        raise ValueError("bad literal run")
                    rgbe[y, x:x + count, c] = raw[at + 1:at + 1 + count]
                    at += 1 + count
                x += count
    if size[0].startswith(b"+"):        # +Y: bottom row first
        rgbe = rgbe[::-1]
    if size[2].startswith(b"-"):
        rgbe = rgbe[:, ::-1]
    e = rgbe[..., 3].astype(np.int32)
    scale = np.where(e > 0, np.ldexp(np.float32(1.0), e - 136), 0.0).astype(np.float32)
    out = np.ones((h, w, 4), np.float32)
    out[..., :3] = rgbe[..., :3].astype(np.float32) * scale[..., None]
    return out
