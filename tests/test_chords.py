"""methods/analytic/chords.py: the planner's screen paths and chord errors, as kernels, equal the
NumPy passes the planner made before (screen_distance_px below), to float64 rounding (the kernel
may fuse a multiply and an add), perspective and orthographic, with points behind the near plane
and at the eye."""

from __future__ import annotations

import numpy as np
import pytest

from warp_blur.core.camera import Projection
from warp_blur.methods.analytic.chords import raise_chord_errors, screen_path_px, straddle_knots


def screen_distance_px(proj: Projection, p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """segments.screen_distance_px as it was: screen distance (pixels) between camera-space points,
    elementwise over (..., 3), points in front of the near plane measured at the near plane."""
    if proj.orthographic:
        return np.linalg.norm((p - q)[..., :2], axis=-1) * proj.pixels_per_unit
    depth = np.maximum(np.minimum(-p[..., 2], -q[..., 2]), proj.near)
    return np.linalg.norm(p - q, axis=-1) / depth * proj.pixels_per_unit


def _points(rng, n):
    p = rng.normal(size=(n, 3)) * 4.0 - (0, 0, 10)
    p[: n // 10, 2] = rng.uniform(-0.05, 2.0, n // 10)   # at or behind the near plane
    p[n // 10] = 0.0                                      # at the eye
    return p


@pytest.mark.parametrize("ortho", [False, True])
def test_screen_paths_and_chord_errors_equal_numpys(ortho):
    rng = np.random.default_rng(int(ortho))
    proj = Projection(ortho, (-0.7, -0.5, 0.7, 0.5), 0.1, 1000.0, 320, 240)
    n = 50_000
    probes = [_points(rng, n) for _ in range(4)]
    expected = sum(screen_distance_px(proj, b, a) for a, b in zip(probes, probes[1:]))
    np.testing.assert_allclose(screen_path_px(proj, probes, threads=2), expected, rtol=1e-12)
    idx = np.sort(rng.choice(n, n // 3, replace=False))
    a, b, truth = probes[0], probes[1], probes[2]
    chords = [screen_distance_px(proj, truth[idx], a[idx] + f * (b[idx] - a[idx])) for f in (0.25, 0.5, 0.75)]
    start = rng.uniform(0, 2, len(idx)) * np.median(chords[1])   # some errors above the chords' and some below
    err, want = start.copy(), start
    for f, chord in zip((0.25, 0.5, 0.75), chords):
        want = np.maximum(want, chord)
        raise_chord_errors(proj, a, b, truth, f, idx, err, threads=2)
    np.testing.assert_allclose(err, want, rtol=1e-12)
    assert (err > start).any() and (err == start).any()


@pytest.mark.parametrize("ortho", [False, True])
def test_few_vertices_take_numpys_passes_with_the_kernels_results(ortho, monkeypatch):
    """Below NUMPY_BELOW vertices the planner's passes run in NumPy (a launch's set-up costs more
    there): the same paths and chord errors as the kernels, non-finite distances inf alike."""
    from warp_blur.methods.analytic import chords
    rng = np.random.default_rng(5 + int(ortho))
    proj = Projection(ortho, (-0.7, -0.5, 0.7, 0.5), 0.1, 1000.0, 320, 240)
    n = 300
    probes = [_points(rng, n) for _ in range(3)]
    probes[1][7] = np.nan
    idx = np.sort(rng.choice(n, 120, replace=False)).astype(np.int64)
    idx[0] = 7
    results = []
    for below in (chords.NUMPY_BELOW, 0):   # NumPy, then the kernels
        monkeypatch.setattr(chords, "NUMPY_BELOW", below)
        err = np.zeros(len(idx))
        for f in (0.25, 0.5):
            raise_chord_errors(proj, probes[0], probes[1], probes[2], f, idx, err)
        results.append((screen_path_px(proj, probes), err))
    (path_np, err_np), (path_k, err_k) = results
    np.testing.assert_allclose(path_np, path_k, rtol=1e-12)
    np.testing.assert_allclose(err_np, err_k, rtol=1e-12)
    assert err_np[0] == np.inf and path_np[7] == np.inf


def _circle(u: np.ndarray, radius: float = 2.0) -> np.ndarray:
    """(len(u), 3) points turning a quarter turn about (0, 0, -10) as u goes 0 -> 1."""
    a = 0.5 * np.pi * u
    return np.stack([radius * np.cos(a), radius * np.sin(a), np.full_like(a, -10.0)], -1)


def test_straddled_chords_follow_an_arc_closer_than_chords_and_still_meet():
    """Eight segments of a quarter turn: with the knots on the arc every chord lies inside it (as
    far as its sagitta); straddled, the path of a vertex (knots joined by straight lines) is within
    the sagitta's 2/3 of the circle everywhere and its mean square distance from it is over 4x
    smaller; the segments meet (one knot each), and a vertex moving in a straight line keeps its knots."""
    k = 8
    u_knots = np.arange(k + 1) / k
    positions = np.stack([np.concatenate([_circle(u_knots[i:i + 1]), [[1.0, 2.0, -5.0 + 3.0 * u_knots[i]]]])
                          for i in range(k + 1)])                          # (k+1, 2, 3): arc, line
    before = positions.copy()
    straddle_knots(positions, {k: np.array([0, 1])},
                   lambda k_u, j: np.concatenate([_circle(np.array([(j + 0.5) / k_u])),
                                                  [[1.0, 2.0, -5.0 + 3.0 * (j + 0.5) / k_u]]]))
    np.testing.assert_array_equal(positions[:, 1], before[:, 1])        # the line: untouched
    sagitta = 2.0 * (1.0 - np.cos(0.5 * np.pi / k / 2))
    u = np.linspace(0.0, 1.0, 4001)
    truth = _circle(u)

    def path(knots):
        x = np.minimum(u * k, k - 1e-12)
        i = x.astype(int)
        f = (x - i)[:, None]
        return knots[i] + f * (knots[i + 1] - knots[i])
    chord_err = np.linalg.norm(path(before[:, 0]) - truth, axis=1)
    straddle_err = np.linalg.norm(path(positions[:, 0]) - truth, axis=1)
    assert chord_err.max() == pytest.approx(sagitta, rel=1e-3)
    assert straddle_err.max() <= (2 / 3 + 0.01) * sagitta
    assert np.mean(straddle_err ** 2) < np.mean(chord_err ** 2) / 4
    radii = np.linalg.norm(positions[:, 0, :2], axis=1)
    assert (radii > 2.0).all()                       # the knots moved outwards, off the arc


def test_straddling_leaves_a_vertex_with_a_non_finite_point_on_its_knots():
    """A midpoint USD returns as NaN or inf (or a knot that overflows) moves no knot: the
    vertex's knots stay as they were, finite, and the curving vertex beside it still moves."""
    k = 4
    knots = np.stack([np.concatenate([_circle(np.array([i / k])), [[0.0, 1.0, -4.0]], [[1e308, 0.0, -3.0]]])
                      for i in range(k + 1)])                          # (k+1, 3, 3)
    before = knots.copy()

    def mid(k_u, j):
        return np.concatenate([_circle(np.array([(j + 0.5) / k_u])), [[np.nan, 1.0, -4.0]], [[-1e308, 0.0, -3.0]]])
    straddle_knots(knots, {k: np.array([0, 1, 2])}, mid)
    np.testing.assert_array_equal(knots[:, 1:], before[:, 1:])
    assert np.isfinite(knots).all()
    assert (np.linalg.norm(knots[:, 0, :2], axis=1) > 2.0).all()
