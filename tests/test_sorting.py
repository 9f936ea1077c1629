"""core/sorting.py: the radix argsort gives NumPy's stable permutation."""

import numpy as np
import pytest

from warp_blur.core.sorting import RADIX_MIN_ITEMS, stable_argsort


@pytest.mark.parametrize("dtype", [np.float32, np.float64, np.int32, np.int64])
def test_stable_argsort_equals_numpys_stable_argsort(dtype):
    """Many ties, negative keys, signed zeros in both orders and infinities, past and below the
    radix threshold."""
    rng = np.random.default_rng(3)
    for n in (0, 5, RADIX_MIN_ITEMS - 1, RADIX_MIN_ITEMS + 1000):
        if np.dtype(dtype).kind == "f":
            keys = np.round(rng.normal(size=n) * 50).astype(dtype) / dtype(4)
            if n > 20:
                keys[3:6], keys[6:9], keys[9:12] = 0.0, -0.0, 0.0
                keys[12], keys[13] = np.inf, -np.inf
        else:
            keys = rng.integers(-1000, 1000, n).astype(dtype)
        got = stable_argsort(keys)
        assert got.dtype == np.int64
        np.testing.assert_array_equal(got, np.argsort(keys, kind="stable"))


def test_nan_keys_sort_as_numpy_does():
    keys = np.linspace(5.0, -5.0, RADIX_MIN_ITEMS + 10)
    keys[::97] = np.nan
    np.testing.assert_array_equal(stable_argsort(keys), np.argsort(keys, kind="stable"))
