"""Tile binning: band culling drops only (entry, tile) pairs that no sample could keep."""

import numpy as np

from warp_blur.core.camera import Projection
from warp_blur.raster.binning import TILE_SIZE, band_misses_tiles, bin_entries


def _kernel_band_keeps(bands: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The kernels' band test (box_rejects) in float32: (P, S) True where sample (x, y) passes."""
    b = bands.astype(np.float32)
    w = b[:, 0:1] * x.astype(np.float32) + b[:, 1:2] * y.astype(np.float32)
    return (w >= b[:, 2:3]) & (w <= b[:, 3:4])


def test_band_culling_never_drops_a_tile_with_a_sample_the_kernel_keeps():
    rng = np.random.default_rng(7)
    pairs = 4000
    angle = rng.uniform(0.0, 2.0 * np.pi, pairs)
    lo = rng.uniform(-400.0, 400.0, pairs)
    bands = np.stack([np.cos(angle), np.sin(angle), lo, lo + rng.uniform(0.5, 40.0, pairs)], axis=1)
    tx, ty = rng.integers(0, 40, pairs), rng.integers(0, 30, pairs)
    # samples anywhere in the tile, its corners and edges included (pixel centres, jitter, edges)
    u = np.concatenate([rng.uniform(0.0, 1.0, 200), [0.0, 1.0, 0.0, 1.0, 0.5]])
    v = np.concatenate([rng.uniform(0.0, 1.0, 200), [0.0, 0.0, 1.0, 1.0, 0.5]])
    x = (tx[:, None] + u[None, :]) * TILE_SIZE
    y = (ty[:, None] + v[None, :]) * TILE_SIZE
    keeps = _kernel_band_keeps(bands, x, y).any(axis=1)
    misses = band_misses_tiles(bands, tx, ty, TILE_SIZE)
    assert not (misses & keeps).any()
    # and it does drop something: the test can tell a useless cull from a working one
    assert misses.sum() > pairs // 4


def test_a_diagonal_streak_lists_only_the_tiles_along_it():
    proj = Projection(False, (-1.0, -0.75, 1.0, 0.75), 0.1, 100.0, 640, 480)
    box = np.array([[0.0, 0.0, 640.0, 480.0]])
    n = np.array([-480.0, 640.0]) / 800.0        # normal of the diagonal (0, 0) -> (640, 480)
    band = np.array([[n[0], n[1], -4.0, 4.0]])
    keep = np.array([True])
    full = bin_entries(proj, box, keep, TILE_SIZE)
    culled = bin_entries(proj, box, keep, TILE_SIZE, bands=band)
    assert full.num_pairs == 40 * 30
    assert 40 <= culled.num_pairs < 200
    # every pixel centre within the band lies in a listed tile
    ys, xs = np.mgrid[0:480, 0:640] + 0.5
    inside = np.abs(n[0] * xs + n[1] * ys) <= 4.0
    tiles = set(np.unique((ys[inside] // TILE_SIZE).astype(int) * 40 + (xs[inside] // TILE_SIZE).astype(int)))
    listed = {t for t in range(40 * 30) if culled.tile_offsets[t + 1] > culled.tile_offsets[t]}
    assert tiles <= listed
