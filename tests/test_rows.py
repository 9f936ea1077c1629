"""core/rows.py: the column-by-column row tests answer what NumPy's reductions answer."""

import numpy as np

from warp_blur.core.rows import all_corners, any_corner, same_rows


def test_same_rows_equals_numpys_reduction():
    """Signed zeros compare equal and a NaN row never does, as with (a == b).all(axis=1)."""
    rng = np.random.default_rng(11)
    a = rng.normal(size=(5000, 3))
    b = a.copy()
    changed = rng.random(5000) < 0.3
    b[changed, rng.integers(0, 3, changed.sum())] += 1.0
    a[:7, 0], b[:7, 0] = 0.0, -0.0
    a[7:9, 1] = np.nan
    b[7, 1] = np.nan
    np.testing.assert_array_equal(same_rows(a, b), (a == b).all(axis=1))
    assert same_rows(a[:0], b[:0]).shape == (0,)


def test_corner_tests_equal_numpys_gathers():
    """Random masks and triangles (repeated corners, unused vertices), and no triangles at all."""
    rng = np.random.default_rng(12)
    for trial in range(20):
        v = int(rng.integers(1, 300))
        mask = rng.random(v) < rng.random()
        tris = rng.integers(0, v, (int(rng.integers(0, 900)), 3)).astype(np.int32)
        np.testing.assert_array_equal(all_corners(mask, tris), mask[tris].all(axis=1))
        np.testing.assert_array_equal(any_corner(mask, tris), mask[tris].any(axis=1))
    empty = np.zeros((0, 3), np.int32)
    assert all_corners(np.ones(4, bool), empty).shape == (0,) and any_corner(np.ones(4, bool), empty).shape == (0,)
