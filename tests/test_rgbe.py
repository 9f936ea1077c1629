"""Radiance RGBE (.hdr) decoding (usd/rgbe.py) against the format's definition: flat and
run-length scanlines, orientation, and a .hdr dome map rendered."""

import os

import numpy as np
import pytest

from warp_blur.usd.rgbe import read_rgbe


def _encode(rgbe: np.ndarray, rle: bool, orientation: bytes = b"-Y %d +X %d") -> bytes:
    """A .hdr file of (H, W, 4) uint8 RGBE: flat scanlines, or per-channel runs (a run for 3+ equal
    bytes, literals otherwise), as Radiance writes them."""
    h, w = rgbe.shape[:2]
    out = bytearray(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\nEXPOSURE=1.0\n\n" + orientation % (h, w) + b"\n")
    for y in range(h):
        if not rle:
            out += rgbe[y].tobytes()
            continue
        out += bytes([2, 2, w >> 8, w & 255])
        for c in range(4):
            row, x = rgbe[y, :, c], 0
            while x < w:
                run = 1
                while x + run < w and run < 127 and row[x + run] == row[x]:
                    run += 1
                if run >= 3:
                    out += bytes([128 + run, row[x]])
                    x += run
                    continue
                lit = x
                while lit < w and lit - x < 128 and not (lit + 2 < w and row[lit] == row[lit + 1] == row[lit + 2]):
                    lit += 1
                out += bytes([lit - x]) + row[x:lit].tobytes()
                x = lit
    return bytes(out)


def _expected(rgbe: np.ndarray) -> np.ndarray:
    e = rgbe[..., 3].astype(np.float64)
    return np.where(e[..., None] > 0, rgbe[..., :3] * 2.0 ** (e[..., None] - 136), 0.0)


@pytest.mark.parametrize("rle", [False, True])
def test_scanlines_decode_to_the_formats_values(rle):
    rng = np.random.default_rng(4)
    rgbe = rng.integers(0, 256, (5, 40, 4)).astype(np.uint8)
    rgbe[..., 3] = rng.integers(120, 140, (5, 40))
    rgbe[1, 5:30] = (200, 100, 50, 130)         # long runs in every channel
    rgbe[2, 3, 3] = 0                           # exponent 0: black
    got = read_rgbe(_encode(rgbe, rle))
    np.testing.assert_allclose(got[..., :3], _expected(rgbe), rtol=1e-6)
    np.testing.assert_allclose(got[..., 3], 1.0)


def test_bottom_up_files_are_flipped_and_bad_files_refused():
    rgbe = np.zeros((3, 8, 4), np.uint8)
    rgbe[0, :, :] = (255, 0, 0, 136)             # first stored row red
    got = read_rgbe(_encode(rgbe, True, b"+Y %d +X %d"))
    assert got[2, 0, 0] == pytest.approx(255.0) and got[0, 0, 0] == 0.0     # +Y: stored bottom row first
    with pytest.raises(ValueError):
        read_rgbe(_encode(rgbe, True)[:-10])       # truncated
    with pytest.raises(ValueError):
        read_rgbe(b"#?RADIANCE\nFORMAT=32-bit_rle_xyze\n\n-Y 1 +X 1\n" + bytes(4))


def test_an_hdr_dome_map_is_read(scene_path):
    """A .hdr latlong map of one colour (3, 1.5, 0.75: beyond 1) is the background as stored."""
    import test_dome
    from pxr import Sdf, Usd, UsdLux

    import warp_blur as wb
    path = test_dome._dome_stage(scene_path(), 0.0, 0.0)
    rgbe = np.zeros((16, 32, 4), np.uint8)
    rgbe[:] = (192, 96, 48, 130)                  # 192 * 2^-6 = 3.0
    with open(os.path.join(os.path.dirname(path), "sky.hdr"), "wb") as f:
        f.write(_encode(rgbe, True))
    stage = Usd.Stage.Open(path)
    UsdLux.DomeLight(stage.GetPrimAtPath("/World/Dome")).GetTextureFileAttr().Set(Sdf.AssetPath("./sky.hdr"))
    stage.GetRootLayer().Save()
    r = wb.render(path, frame=1, method="accumulation", samples=1, resolution=(16, 16))
    assert not r.stats["warnings"]
    np.testing.assert_allclose(r.rgba[8, 8, :3], (3.0, 1.5, 0.75), rtol=1e-4)
