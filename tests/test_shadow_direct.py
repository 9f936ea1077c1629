"""shadows/direct.py: a splatted depth map (each triangle over its rows' spans, perspective edge
crosses computed once) equals the per-texel gather of the same triangles (the tile-binned
nearest hit), texel for texel, in orthographic and perspective faces, with slivers, huge
triangles and triangles crossing behind the eye."""

from __future__ import annotations

import numpy as np
import pytest
import warp as wp

from warp_blur.raster.device_data import TriangleTables
from warp_blur.shadows.direct import FaceRasterizer, still_triangles
from warp_blur.shadows.layout import Face, Sample

SIZE = 64


def random_scene(seed: int, perspective: bool) -> tuple[np.ndarray, np.ndarray]:
    """(V, 3) camera-space positions and (T, 3) triangles: small and sliver triangles in front of
    the face, a few huge ones, and (perspective) some with a vertex behind the eye."""
    rng = np.random.default_rng(seed)
    n = 120
    centres = np.stack([rng.uniform(-2, 2, n), rng.uniform(-2, 2, n), rng.uniform(-9, -3, n)], axis=1)
    sizes = rng.choice([0.05, 0.4, 1.5, 30.0], n, p=[0.3, 0.4, 0.25, 0.05])
    corners = centres[:, None] + rng.normal(size=(n, 3, 3)) * sizes[:, None, None]
    corners[:n // 6, 1] = corners[:n // 6, 0] + 1e-3 * rng.normal(size=(n // 6, 3))   # slivers
    if perspective:
        corners[-6:, 0, 2] = rng.uniform(0.5, 3.0, 6)   # a vertex behind the eye
    return corners.reshape(-1, 3), np.arange(3 * n, dtype=np.int32).reshape(n, 3)


@pytest.mark.parametrize("perspective", [False, True])
@pytest.mark.parametrize("seed", [0, 1])
def test_splatted_depth_equals_the_per_texel_gather(perspective, seed):
    positions, tris = random_scene(seed, perspective)
    t = len(tris)
    tables = TriangleTables(tris, np.zeros(t, np.int32), np.zeros(t, np.int32), np.zeros((3 * t, 3), np.float32), "cpu")
    face = Face(np.eye(3), (-1.0, -1.0, 1.0, 1.0), False, 0.1) if perspective else \
        Face(np.eye(3), (-2.5, -2.5, 2.5, 2.5), True, -1e30)
    sample = Sample(positions, np.ones(t, bool), np.zeros((0, 18), np.float32))
    raster = FaceRasterizer(tables, tris, SIZE, "cpu")
    a, shift = np.eye(3), np.zeros(3)
    for threads in (1, 2):
        splat = raster.depth_over(a, shift, face, sample, None, None, threads)
        gathered = raster.gather(a, shift, face, sample, threads)[0].numpy().reshape(SIZE, SIZE)
        assert np.isfinite(splat).mean() > 0.3                  # the triangles really cover the face
        np.testing.assert_array_equal(splat, gathered)
    # over a base: the nearer of the base and the triangles
    base = np.full((SIZE, SIZE), 6.0, np.float32)
    over = raster.depth_over(a, shift, face, sample, None, base, 2)
    np.testing.assert_array_equal(over, np.minimum(base, gathered))


def test_still_triangles_are_judged_in_the_lights_frame():
    """A camera that moves carries every point and the light's frame alike: nothing moved in the
    light's frame. A vertex moved in the world makes its triangle not still."""
    positions = np.array([[0, 0, -5], [1, 0, -5], [0, 1, -5], [2, 2, -6], [3, 2, -6], [2, 3, -6]], float)
    tris = np.array([[0, 1, 2], [3, 4, 5]], np.int32)
    light = np.zeros((1, 18), np.float32)
    light[0, 4:7] = (0, 5, 0)            # origin
    light[0, 10:13] = (1, 0, 0)          # local x
    light[0, 13:16] = (0, 0, 1)          # local y
    probes = []
    for k in range(4):
        shift = np.array([0.3 * k, -0.1 * k, 0.2 * k])   # the camera moves: everything shifts in camera space
        p = positions + shift
        if k == 3:
            p[4] += (0.0, 0.5, 0.0)      # and one vertex of the second triangle moves in the world
        row = light.copy()
        row[0, 4:7] += shift
        probes.append(Sample(p, np.ones(2, bool), row))
    np.testing.assert_array_equal(still_triangles(probes, 0, tris), [True, False])


@pytest.mark.parametrize("perspective", [False, True])
def test_instants_splatted_together_equal_each_instant_splatted_alone(perspective):
    """A face's instants splatted in one launch, texel-major over a base, equal each instant's own
    map over the same base; the touched flags cover every texel whose depth differs between
    instants, and no texel outside the triangles' reach."""
    positions, tris = random_scene(2, perspective)
    t = len(tris)
    tables = TriangleTables(tris, np.zeros(t, np.int32), np.zeros(t, np.int32), np.zeros((3 * t, 3), np.float32), "cpu")
    face = Face(np.eye(3), (-1.0, -1.0, 1.0, 1.0), False, 0.1) if perspective else \
        Face(np.eye(3), (-2.5, -2.5, 2.5, 2.5), True, -1e30)
    raster = FaceRasterizer(tables, tris, SIZE, "cpu")
    times = 4
    rng = np.random.default_rng(3)
    visible = rng.random(t) < 0.5          # the triangles that move; the rest are the base
    samples, transforms = [], []
    for b in range(times):
        moved = positions.copy()
        moved[tris[visible].ravel()] += (0.15 * b, -0.1 * b, 0.05 * b)
        samples.append(Sample(moved, np.ones(t, bool), np.zeros((0, 18), np.float32)))
        transforms.append((np.eye(3), np.zeros(3)))
    base = raster.depth_over(np.eye(3), np.zeros(3), face, samples[0], ~visible, None, 1)
    geo = raster.instants_geometry(transforms, samples, list(range(times)), times, visible)
    laid = np.ascontiguousarray(np.repeat(base[..., None], times, axis=2))
    target = wp.array(laid.ravel(), dtype=float, device="cpu")
    touched = wp.zeros(SIZE * SIZE, dtype=wp.uint8, device="cpu")
    raster.splat_instants(face, geo, times, target, touched, 2)
    together = target.numpy().reshape(SIZE, SIZE, times)
    for b in range(times):
        alone = raster.depth_over(np.eye(3), np.zeros(3), face, samples[b], visible, base, 1)
        np.testing.assert_array_equal(together[..., b], alone)
    varies = (together != together[..., :1]).any(axis=2)
    flags = touched.numpy().reshape(SIZE, SIZE).astype(bool)
    assert varies.any() and not (varies & ~flags).any()
    assert not flags[np.isinf(together).all(axis=2)].any()   # nothing drew where every instant is empty
