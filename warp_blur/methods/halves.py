"""A frame's error estimate without a reference (stats["error_estimate"]): the RMS difference, over
every pixel and the four RGBA channels, between the frame and the same frame made from only its
even-indexed instants (accumulation), time samples (stochastic, one per stratum) or time slots
(analytic's bitmask resolve).

Where the error falls as 1/N (a blurred edge's coverage, sampled at N instants or N strata) the
half frame's error is about twice the frame's and this difference about the frame's own error;
where it is noise (independent samples) the difference is the frame's noise exactly. Measured on
the bench scenes against accumulation-4096 (bench_tradeoff.py's `estimate` column) it comes out
at 1 to 4 times the true RMSE: an upper estimate, never a measurement of it. It sees only what
halving the samples changes: not analytic's motion linearisation or shading pieces, not the
shadow maps' resolution, not velocity blur's approximation (no estimate there).
"""

from __future__ import annotations

import numpy as np
import warp as wp


def rms(diff: np.ndarray) -> float:
    """sqrt(mean(diff²)) over a (P, 4) (or (H, W, 4)) difference image (BLAS's scaled norm: a
    float64 copy of a 640×480 frame's four channels took 3-16 ms, the norm 0.2 ms)."""
    d = np.ascontiguousarray(diff).ravel()
    return float(np.linalg.norm(d)) / float(np.sqrt(d.size)) if d.size else 0.0


class InstantHalves:
    """Accumulation's image as two sums: the even-indexed instants' passes add into `even`, the odd
    ones' into `odd` ((P, 4) float32 each; one array when there is one instant). Passes that add
    a pixel at full weight (the same at every instant) add into `even` too; those pixels are
    exact and named to estimate()."""

    def __init__(self, num_pixels: int, instants: int, device: str) -> None:
        self.instants = instants
        self.even = wp.zeros((num_pixels, 4), dtype=float, device=device)
        self.odd = wp.zeros((num_pixels, 4), dtype=float, device=device) if instants > 1 else self.even

    def target(self, i: int) -> wp.array:
        """The sum instant i's pass adds into."""
        return self.odd if i % 2 else self.even

    def image(self) -> np.ndarray:
        """(P, 4) the frame: both sums."""
        even = self.even.numpy()
        return even + self.odd.numpy() if self.odd is not self.even else even

    def estimate(self, exact_pixels: np.ndarray | None = None) -> float | None:
        """The frame minus its even instants' average (None for one instant): odd − even × n_odd /
        n_even, zero at exact_pixels (those added at full weight: flat indices or a (P,) mask)."""
        if self.odd is self.even:
            return None
        n_even = (self.instants + 1) // 2
        diff = self.odd.numpy() - self.even.numpy() * ((self.instants - n_even) / n_even)
        if exact_pixels is not None and len(exact_pixels):
            diff[exact_pixels] = 0.0
        return rms(diff)
