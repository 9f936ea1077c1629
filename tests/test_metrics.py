"""Metrics agree with hand-computed values on small arrays (RMSE over all values, alpha included)."""

import math

import numpy as np
import pytest

from warp_blur.output.metrics import compare_images, max_abs, psnr, rmse, share_above, ssim


def test_hand_computed_values():
    a = np.zeros((1, 2, 4), np.float32)
    b = np.zeros((1, 2, 4), np.float32)
    b[0, 0, 0] = 0.4      # one value off by 0.4 among 8
    b[0, 1, 3] = -0.2     # alpha counts too
    assert rmse(a, b) == pytest.approx(math.sqrt((0.16 + 0.04) / 8))
    assert max_abs(a, b) == pytest.approx(0.4)
    assert share_above(a, b, 0.3) == 0.5
    assert psnr(a, b) == pytest.approx(20 * math.log10(1 / math.sqrt(0.2 / 8)))
    assert psnr(a, a) == math.inf


def test_ssim_identical_and_different():
    rng = np.random.default_rng(0)
    a = rng.random((32, 32, 4)).astype(np.float32)
    assert ssim(a, a) == pytest.approx(1.0)
    assert ssim(a, rng.random((32, 32, 4)).astype(np.float32)) < 0.5
    report = compare_images(a, a)
    assert report["rmse"] == 0 and report["ssim"] == pytest.approx(1.0)
