"""texture_lookup's bilinear reads at texture coordinates far outside [0, 1], in every wrap mode,
against a NumPy reference of USD's wrap rules (the kernel's shortcuts for whole periods must read
the same texels)."""

from __future__ import annotations

import numpy as np
import pytest
import warp as wp

from warp_blur.kernels.kernel_types import Textures
from warp_blur.kernels.texture_lookup import bilinear

W, H = 5, 3   # odd, non-square: a swapped axis or period shows


@wp.kernel(enable_backward=False)
def read_bilinear(tx: Textures, uvs: wp.array(dtype=wp.vec2), wrap_s: int, wrap_t: int,
                  out: wp.array(dtype=wp.vec4)):
    i = wp.tid()
    out[i] = bilinear(tx, 0, uvs[i], wrap_s, wrap_t)


def wrapped(i: int, n: int, mode: int) -> int:
    """USD's wrap of texel index i into [0, n): repeat, mirror, clamp, or -1 (black)."""
    if 0 <= i < n:
        return i
    if mode == 0:
        return i % n
    if mode == 1:
        p = i % (2 * n)
        return 2 * n - 1 - p if p >= n else p
    if mode == 2:
        return min(max(i, 0), n - 1)
    return -1


def reference(img: np.ndarray, uv: np.ndarray, ws: int, wt: int) -> np.ndarray:
    """Texel-centre bilinear of img (H, W, 4) at uv (t = 0 at the bottom row), in float64."""
    x = uv[0] * W - 0.5
    y = (1.0 - uv[1]) * H - 0.5
    x0, y0 = int(np.floor(x)), int(np.floor(y))
    fx, fy = x - x0, y - y0

    def texel(xi: int, yi: int) -> np.ndarray:
        a, b = wrapped(xi, W, ws), wrapped(yi, H, wt)
        return np.zeros(4) if a < 0 or b < 0 else img[b, a]
    top = texel(x0, y0) * (1 - fx) + texel(x0 + 1, y0) * fx
    bottom = texel(x0, y0 + 1) * (1 - fx) + texel(x0 + 1, y0 + 1) * fx
    return top * (1 - fy) + bottom * fy


@pytest.mark.parametrize("ws,wt", [(0, 0), (1, 1), (2, 2), (3, 3), (0, 1), (2, 0)])
def test_bilinear_wraps_coordinates_many_periods_away(ws, wt):
    rng = np.random.default_rng(7)
    img = rng.random((H, W, 4)).astype(np.float32)
    tx = Textures()
    tx.texels = wp.array(img.reshape(-1, 4), dtype=wp.vec4, device="cpu")
    tx.levels = wp.array(np.array([[0, W, H]], np.int32), dtype=int, device="cpu")
    tx.textures = wp.array(np.array([[0, 1, ws, wt]], np.int32), dtype=int, device="cpu")
    tx.bindings = wp.zeros((1, 18), dtype=float, device="cpu")
    # texel centres, their edges and points between, from -3.7 to +3.7 periods, and far away
    grid = np.concatenate([np.linspace(-3.7, 3.7, 149), [-40.3, 17.9, 0.0, 1.0, -1.0, 2.0]])
    uv = np.stack(np.meshgrid(grid, grid[::-1]), -1).reshape(-1, 2).astype(np.float32)
    out = wp.zeros(len(uv), dtype=wp.vec4, device="cpu")
    wp.launch(read_bilinear, dim=len(uv), inputs=[tx, wp.array(uv, dtype=wp.vec2, device="cpu"), ws, wt, out],
              device="cpu")
    got = out.numpy()
    want = np.array([reference(img.astype(np.float64), p.astype(np.float64), ws, wt) for p in uv])
    assert np.abs(got - want).max() < 2e-5
