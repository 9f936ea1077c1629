"""shadows/vertex_passes.light_fit: a distant light's bounds, extent, count and stillness from
kernel bands equal the NumPy passes maps.ShadowMaps._plan made (and still makes for other lights):
points beyond the fit limit and NaN points left out of the bounds, a moving camera and light, a
probe that sees a different number of points (no stillness then)."""

from __future__ import annotations

import numpy as np
import pytest

from warp_blur.shadows.layout import light_frame
from warp_blur.shadows.vertex_passes import light_fit

LIMIT = 1.0e18


def _frame(rng, shift):
    row = np.zeros(18, np.float32)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    row[4:7] = rng.normal(size=3) * 5 + shift
    row[7:10], row[10:13], row[13:16] = q[2], q[0], q[1]
    return light_frame(row)


def _numpy_fit(probes):
    locs = [(p[idx] - o) @ m.T for p, idx, (o, m) in probes]
    allp = np.concatenate(locs)
    with np.errstate(invalid="ignore"):
        allp = allp[(np.abs(allp) <= LIMIT).all(axis=1)]
        change = None
        if all(a.shape == locs[0].shape for a in locs[1:]):
            change = max(float(np.abs(a - locs[0]).max(initial=0.0)) for a in locs[1:])
    return allp.min(axis=0), allp.max(axis=0), float(np.abs(allp).max()), len(allp), change


@pytest.mark.parametrize("seed", range(4))
def test_light_fit_equals_numpys_passes(seed):
    rng = np.random.default_rng(seed)
    n = 200_000
    base = rng.normal(size=(n, 3)) * 30.0
    probes = []
    for k in range(3):
        shift = rng.normal(size=3) * k
        p = base + shift
        p[rng.random(n) < 0.01] += rng.normal(size=3)            # a few points move in the world
        p[5] = (1e20, 0, 0)                                      # beyond the fit
        if seed % 2:
            p[6] = np.nan
        idx = np.flatnonzero(rng.random(n) < 0.9) if seed == 3 and k == 2 else np.arange(0, n, 2)
        probes.append((p, idx, _frame(np.random.default_rng(100 + seed), shift)))
    lo, hi, top, count, change = light_fit(probes, LIMIT, threads=2)
    n_lo, n_hi, n_top, n_count, n_change = _numpy_fit(probes)
    np.testing.assert_allclose(lo, n_lo, rtol=1e-13)
    np.testing.assert_allclose(hi, n_hi, rtol=1e-13)
    assert top == pytest.approx(n_top, rel=1e-13) and count == n_count
    if seed == 3:
        assert change is None and n_change is None
    elif seed % 2:
        assert change == np.inf and np.isnan(n_change)          # a NaN point: never still
    else:
        assert change == pytest.approx(n_change, rel=1e-9) and change > 0.1
