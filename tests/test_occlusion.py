"""Occlusion culling's depth bound for a whole entry (occlusion.plane_beyond, behind plane_hidden):
it may claim that a moving triangle's plane lies beyond a depth along a ray at every time of its
span only where the depths the fill would compute (moving.depth_at) all do."""

import numpy as np
import warp as wp

from moving_cases import case_triangle, random_moving_cases
from warp_blur.methods.analytic.moving import Moving, depth_at, depth_polynomials
from warp_blur.methods.analytic.occlusion import plane_beyond

SAMPLES = 400
#: the depth each case is asked about, as a multiple of the smallest depth_at sampled over the span
FACTORS = (0.5, 0.9, 0.99, 0.998, 0.9995, 1.0, 1.0001, 1.001, 1.1)


@wp.kernel(enable_backward=False)
def _beyond(p0: wp.array2d(dtype=wp.vec3), p1: wp.array2d(dtype=wp.vec3), origins: wp.array(dtype=wp.vec3),
            dirs: wp.array(dtype=wp.vec3), factors: wp.array(dtype=float), samples: int,
            beyond: wp.array2d(dtype=int), smallest: wp.array(dtype=float)):
    """Case i (triangle p0[i] moving to p1[i], ray (origins[i], dirs[i])): the smallest depth_at
    over samples + 1 entry times, and plane_beyond at each factor times it."""
    i = wp.tid()
    m = case_triangle(p0, p1, i)
    o = origins[i]
    d = dirs[i]
    lo = float(wp.inf)
    for k in range(samples + 1):
        lo = wp.min(lo, depth_at(m, o, d, float(k) / float(samples)))
    smallest[i] = lo
    num, den = depth_polynomials(m, o, d)
    for j in range(factors.shape[0]):
        beyond[i, j] = int(plane_beyond(m, o, d, num, den, factors[j] * lo))


def _cases(seed: int, n: int, degenerate: bool):
    """plane_beyond's claims (cases whose plane is in front of the eye at every sample, FACTORS)
    over random_moving_cases around depth 8 (slivers where degenerate)."""
    p0, p1, _times, origins, dirs = random_moving_cases(np.random.default_rng(seed), n, depth=8.0, move=2.0,
                                                        degenerate=degenerate)
    beyond = wp.zeros((n, len(FACTORS)), dtype=int)
    smallest = wp.zeros(n, dtype=float)
    wp.launch(_beyond, dim=n, inputs=[wp.array(p0, dtype=wp.vec3), wp.array(p1, dtype=wp.vec3),
                                      wp.array(origins, dtype=wp.vec3), wp.array(dirs, dtype=wp.vec3),
                                      wp.array(np.array(FACTORS), dtype=float), SAMPLES],
              outputs=[beyond, smallest], device="cpu")
    front = smallest.numpy() > 0.0   # the plane in front of the eye at every sample
    return beyond.numpy()[front].astype(bool)


def test_plane_beyond_claims_only_what_every_depth_shows():
    """At or beyond the smallest sampled depth, never a claim; clearly nearer (1%), most cases
    (those whose plane never turns edge-on to the ray); within its slack (0.05%), none."""
    beyond = _cases(7, 6000, degenerate=False)
    share = dict(zip(FACTORS, beyond.mean(axis=0)))
    assert len(beyond) > 4000
    for f in (1.0, 1.0001, 1.001, 1.1, 0.9995):
        assert share[f] == 0.0, (f, share[f])
    assert share[0.5] > 0.95 and share[0.9] > 0.9 and share[0.99] > 0.8
    # a claim at one depth holds at every nearer one
    assert (beyond[:, :-1] >= beyond[:, 1:]).all()


def test_plane_beyond_makes_no_claim_for_degenerate_triangles():
    """A triangle that is a sliver at both ends of its span: its depths are rounding noise there,
    so nothing is claimed even at half the smallest sampled depth."""
    beyond = _cases(8, 6000, degenerate=True)
    assert len(beyond) > 2000
    assert not beyond.any()


@wp.kernel(enable_backward=False)
def _beyond_polynomials(num: wp.vec4, den: wp.vec4, z: float, out: wp.array(dtype=int)):
    m = Moving()
    m.a0 = wp.vec3(0.0, 0.0, -2.0)
    m.b0 = wp.vec3(1.0, 0.0, -2.0)
    m.c0 = wp.vec3(0.0, 1.0, -2.0)
    m.a1 = m.a0
    m.b1 = m.b0
    m.c1 = m.c0
    m.u1 = 1.0
    out[0] = int(plane_beyond(m, wp.vec3(0.0, 0.0, 0.0), wp.vec3(0.0, 0.0, -1.0), num, den, z))


def _claims(num, den, z) -> bool:
    out = wp.zeros(1, dtype=int)
    wp.launch(_beyond_polynomials, dim=1, inputs=[wp.vec4(*num), wp.vec4(*den), z], outputs=[out], device="cpu")
    return bool(out.numpy()[0])


def test_plane_beyond_needs_one_sign_of_d_throughout():
    """N = 10 over D = 1 - 6 s + 6 s² is 10 at both ends of the span, but D turns negative in
    between (the plane turns past edge-on to the ray and back), where the depth is negative:
    no claim, though N - z D is positive throughout. With D = 1 + s² it holds everywhere."""
    assert not _claims((10.0, 0.0, 0.0, 0.0), (1.0, -6.0, 6.0, 0.0), 1.0)
    assert _claims((10.0, 0.0, 0.0, 0.0), (1.0, 0.0, 1.0, 0.0), 1.0)
    assert not _claims((10.0, 0.0, 0.0, 0.0), (1.0, 0.0, 1.0, 0.0), 5.0)   # 10 / 2 at s = 1
