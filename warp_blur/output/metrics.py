"""Image error metrics shared by tests, benchmarks, stats and `warp-blur compare`.

All metrics treat an image as every H×W×C value (alpha included), as the acceptance README does.
"""

from __future__ import annotations

import numpy as np


def rmse(a: np.ndarray, b: np.ndarray) -> float:
    """Root mean square error over all values."""
    d = np.asarray(a, np.float64) - np.asarray(b, np.float64)
    return float(np.sqrt(np.mean(d * d)))


def psnr(a: np.ndarray, b: np.ndarray, peak: float = 1.0) -> float:
    """Peak signal-to-noise ratio in dB (inf for identical images)."""
    e = rmse(a, b)
    return float("inf") if e == 0 else float(20.0 * np.log10(peak / e))


def max_abs(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(np.asarray(a, np.float64) - np.asarray(b, np.float64)))) if np.size(a) else 0.0


def share_above(a: np.ndarray, b: np.ndarray, threshold: float) -> float:
    """Share of pixels whose largest channel error exceeds `threshold`."""
    d = np.abs(np.asarray(a, np.float64) - np.asarray(b, np.float64))
    if d.ndim == 3:
        d = d.max(axis=-1)
    return float(np.mean(d > threshold))


def ssim(a: np.ndarray, b: np.ndarray, data_range: float = 1.0) -> float:
    """Mean structural similarity over channels (scikit-image's implementation, 7×7 windows)."""
    from skimage.metrics import structural_similarity
    a = np.asarray(a, np.float64)
    b = np.asarray(b, np.float64)
    win = min(7, min(a.shape[0], a.shape[1]) // 2 * 2 - 1)
    if win < 3:
        return float("nan")
    return float(structural_similarity(a, b, data_range=data_range, channel_axis=-1 if a.ndim == 3 else None,
                                       win_size=win))


def compare_images(a: np.ndarray, b: np.ndarray, threshold: float = 0.01) -> dict:
    """Every metric at once (the `compare` command's report)."""
    report = {"rmse": rmse(a, b), "psnr": psnr(a, b), "max_abs": max_abs(a, b),
              "share_above": share_above(a, b, threshold), "threshold": threshold}
    try:
        report["ssim"] = ssim(a, b)
    except ImportError:
        pass
    return report
