"""Float32 vs a float64 run of the same kernel code (issue 8): the analytic method's coverage
functions (methods/analytic/coverage.py) are generic over the float type; the renderer runs them
in float32, and here they run in float64 too on the same cases.

Tolerance: the covered shutter time may differ by less than 1/1024 of the shutter, the finest
time slot the SPEC's bitmask offers (so float32 never changes a 1024-bit resolve by more than a
slot at an edge); the numbers of covered pieces must agree on all but 1% of the pairs.
"""

import os

import numpy as np
import pytest
from conftest import SCENES

from warp_blur.tools.precision import compare_coverage, coverage_precision

SLOT = 1.0 / 1024


def test_closed_form_translating_triangle_in_both_precisions():
    """A triangle sliding across a ray at constant speed covers it for (its width along the path)
    / (the path length) of the span: both precisions match the closed form."""
    # triangle with a vertical edge at x = -0.5 and x-extent 1 at the ray's height, sliding +4 in x
    tri = np.array([[-0.5, -1.0, -5.0], [-0.5, 1.0, -5.0], [1.5, 0.0, -5.0]])
    p0 = (tri - [2.0, 0.0, 0.0])[None]
    p1 = (tri + [2.0, 0.0, 0.0])[None]
    res = compare_coverage(p0, p1, np.zeros((1, 3)), np.array([[0.0, 0.5 / 5.0, -1.0]]), np.array([[0, 1, 2]]))
    assert res.covered == 1 and res.max_dt < 1e-6
    # at y = 0.5 the triangle spans x in [-0.5, 0.5]: width 1 over a path of 4
    from warp_blur.tools.precision import _run
    c64, n64 = _run(p0, p1, np.zeros((1, 3)), np.array([[0.0, 0.5 / 5.0, -1.0]]), np.array([[0, 1, 2]]), True, "cpu")
    assert n64[0] == 1 and abs(c64[0] - 0.25) < 1e-12


def test_random_moving_triangles_at_large_and_tiny_scale():
    """Camera-relative cases, as the renderer makes them: far geometry at depth 1e3 and small
    triangles 1e-3 across, moving and turning."""
    rng = np.random.default_rng(3)
    for depth, size in ((5.0, 1.0), (1.0e3, 50.0), (2.0, 1.0e-3)):
        n = 4000
        centre = np.array([0.0, 0.0, -depth])
        p0 = centre + rng.normal(size=(n, 3, 3)) * size
        p1 = p0 + rng.normal(size=(n, 1, 3)) * size + rng.normal(size=(n, 3, 3)) * 0.3 * size
        d = np.concatenate([rng.normal(size=(n, 2)) * size / depth, -np.ones((n, 1))], 1)
        res = compare_coverage(p0, p1, np.zeros((n, 3)), d, np.tile([0, 1, 2], (n, 1)))
        assert res.covered > n // 10
        assert res.max_dt < SLOT, (depth, size, res)
        assert res.piece_mismatches <= n // 100


@pytest.mark.parametrize("scene,frame", [("demo.usda", 12), ("shadows.usda", 6)])
def test_shipped_scenes_coverage_float32_vs_float64(scene, frame):
    res = coverage_precision(os.path.join(SCENES, scene), frame, (96, 72), max_pairs=4000)
    assert res.pairs > 100 and res.covered > 20
    assert res.max_dt < SLOT, res
    assert res.piece_mismatches <= res.pairs // 100
