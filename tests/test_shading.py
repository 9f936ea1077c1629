"""kernels/shading.py: the BRDF against the closed form SPEC §4 states, evaluated in float64."""

from __future__ import annotations

import numpy as np
import warp as wp

from warp_blur.kernels.shading import brdf


@wp.kernel(enable_backward=False)
def _brdf_cases(n: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3), l: wp.array(dtype=wp.vec3),
                diffuse: wp.array(dtype=wp.vec3), f0: wp.array(dtype=wp.vec3), roughness: wp.array(dtype=float),
                out: wp.array(dtype=wp.vec3)):
    i = wp.tid()
    out[i] = brdf(n[i], v[i], l[i], diffuse[i], f0[i], roughness[i])


@wp.kernel(enable_backward=False)
def _brdf_headlit(n: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3), diffuse: wp.array(dtype=wp.vec3),
                  f0: wp.array(dtype=wp.vec3), roughness: wp.array(dtype=float), out: wp.array(dtype=wp.vec3)):
    """brdf with the normal and the view normalised in float32, as the renderer's are, and the
    light along the view (a headlight)."""
    i = wp.tid()
    view = wp.normalize(v[i])
    out[i] = brdf(wp.normalize(n[i]), view, view, diffuse[i], f0[i], roughness[i])


def _unit(rng: np.random.Generator, count: int) -> np.ndarray:
    x = rng.normal(size=(count, 3))
    return x / np.linalg.norm(x, axis=1, keepdims=True)


def _closed_form(n, v, l, diffuse, f0, roughness) -> np.ndarray:
    """Lambert + GGX: D with alpha = roughness², Schlick-GGX G with k = alpha / 2, Schlick F."""
    nl = np.sum(n * l, axis=1)
    nv = np.sum(n * v, axis=1)
    h = l + v
    h /= np.linalg.norm(h, axis=1, keepdims=True)
    nh = np.maximum(np.sum(n * h, axis=1), 0.0)
    vh = np.maximum(np.sum(v * h, axis=1), 0.0)
    a = roughness ** 2
    dist = a ** 2 / (np.pi * (nh ** 2 * (a ** 2 - 1.0) + 1.0) ** 2)
    k = a / 2.0
    g = nl / (nl * (1.0 - k) + k) * nv / (nv * (1.0 - k) + k)
    fres = f0 + (1.0 - f0) * ((1.0 - vh) ** 5)[:, None]
    spec = fres * (dist * g / (4.0 * nl * nv))[:, None]
    lit = (nl > 0.0) & (nv > 0.0)
    return diffuse / np.pi + np.where(lit[:, None], spec, 0.0)


def test_brdf_matches_the_closed_form_in_float64():
    rng = np.random.default_rng(7)
    count = 4000
    n = _unit(rng, count)
    v = _unit(rng, count)
    l = _unit(rng, count)
    # grazing views and lights included: (1 - v·h)^5 is largest there
    v[:200] = n[:200] * 0.02 + _unit(rng, 200)
    v[:200] /= np.linalg.norm(v[:200], axis=1, keepdims=True)
    # most cases lit and seen (light and view on the normal's side); the first 400 anywhere
    for x in (v, l):
        x[400:] *= np.sign(np.sum(x[400:] * n[400:], axis=1))[:, None]
    diffuse = rng.uniform(0.0, 1.0, (count, 3))
    f0 = rng.uniform(0.0, 1.0, (count, 3))
    roughness = rng.uniform(0.05, 1.0, count)
    arrays = [wp.array(x.astype(np.float32), dtype=wp.vec3, device="cpu") for x in (n, v, l, diffuse, f0)]
    out = wp.zeros(count, dtype=wp.vec3, device="cpu")
    wp.launch(_brdf_cases, dim=count, inputs=[*arrays, wp.array(roughness.astype(np.float32), device="cpu"), out],
              device="cpu")
    got = out.numpy().astype(np.float64)
    # the reference from the float32-rounded inputs the kernel saw
    r32 = [x.astype(np.float32).astype(np.float64) for x in (n, v, l, diffuse, f0, roughness)]
    want = _closed_form(*r32)
    assert np.all(np.isfinite(got))
    rel = np.abs(got - want) / np.maximum(np.abs(want), 1e-3)
    assert rel.max() < 2e-3, rel.max()
    # and the lit share is not trivially diffuse: the specular lobe is exercised
    assert np.mean(np.abs(want - r32[3] / np.pi).max(axis=1) > 1e-2) > 0.5


def test_brdf_stays_finite_where_normal_view_and_light_align():
    """The smoothest surface the materials allow (roughness 0.02) seen and lit along its normal
    (a headlight on a face turning through the view): unit vectors rounded to float32 can make
    n·h a hair above 1, where the GGX denominator cancels to 0. Every value must stay finite, and
    no larger than the lobe's peak, 1 / (π α²) scaled by the Fresnel and geometry terms."""
    rng = np.random.default_rng(11)
    count = 20000
    base = _unit(rng, count)
    n = base + rng.normal(scale=1e-7, size=(count, 3))
    v = base + rng.normal(scale=1e-7, size=(count, 3))
    diffuse = np.full((count, 3), 0.5)
    f0 = np.full((count, 3), 0.04)
    roughness = np.full(count, 0.02)
    arrays = [wp.array(x.astype(np.float32), dtype=wp.vec3, device="cpu") for x in (n, v, diffuse, f0)]
    out = wp.zeros(count, dtype=wp.vec3, device="cpu")
    wp.launch(_brdf_headlit, dim=count, inputs=[*arrays, wp.array(roughness.astype(np.float32), device="cpu"), out],
              device="cpu")
    got = out.numpy()
    assert np.all(np.isfinite(got))
    alpha = 0.02 ** 2
    peak = 0.5 / np.pi + 1.0 / (np.pi * alpha ** 2) / 4.0   # F ≤ 1, G ≤ 1, n·l = n·v = 1
    assert got.max() <= peak * 1.01
