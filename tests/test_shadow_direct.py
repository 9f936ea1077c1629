"""shadows/direct.py: a splatted depth map (each triangle over its rows' spans, perspective edge
crosses computed once) equals the per-texel gather of the same triangles (the tile-binned
nearest hit), texel for texel, in orthographic and perspective faces, with slivers, huge
triangles and triangles crossing behind the eye."""

from __future__ import annotations

import numpy as np
import pytest
import warp as wp

from warp_blur.raster.device_data import TriangleTables
from warp_blur.shadows.direct import STILL_TOL, FaceRasterizer, still_triangles
from warp_blur.shadows.layout import Face, Sample, light_frame

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
    geo = raster.instants_geometry(transforms, samples, list(range(times)), times, visible, face)
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


def closed_scene(seed: int, light_inside: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Interpenetrating closed meshes (spheres and boxes, one wound inward) in front of the face,
    and an open sheet behind them: (V, 3) positions, (T, 3) triangles, (T,) object ids.
    light_inside: one more box around the eye (the light inside a closed instance)."""
    import trimesh
    rng = np.random.default_rng(seed)
    parts = [trimesh.creation.icosphere(subdivisions=2, radius=rng.uniform(0.5, 1.5)) if i % 2 else
             trimesh.creation.box(extents=rng.uniform(0.5, 2.0, 3)) for i in range(6)]
    for mesh in parts:
        mesh.apply_transform(trimesh.transformations.random_rotation_matrix(rng.random(3)))
        mesh.apply_translation([rng.uniform(-1.5, 1.5), rng.uniform(-1.5, 1.5), rng.uniform(-8.0, -4.0)])
    parts[2].invert()   # wound inward: its volume is negative, its back faces face the other way
    parts.append(trimesh.Trimesh([[-3, -3, -9.5], [3, -3, -9.5], [3, 3, -9.5], [-3, 3, -9.5]], [[0, 1, 2], [0, 2, 3]]))
    if light_inside:
        parts.append(trimesh.creation.box(extents=(1.0, 1.0, 1.0)))
    positions, tris, objects, start = [], [], [], 0
    for i, mesh in enumerate(parts):
        positions.append(np.asarray(mesh.vertices, np.float64))
        tris.append(np.asarray(mesh.faces, np.int32) + start)
        objects.append(np.full(len(mesh.faces), i, np.int32))
        start += len(mesh.vertices)
    return np.concatenate(positions), np.concatenate(tris), np.concatenate(objects)


@pytest.mark.parametrize("perspective", [False, True])
@pytest.mark.parametrize("light_inside", [False, True])
def test_back_faces_of_closed_instances_change_no_texel(perspective, light_inside):
    """Leaving out the back faces of closed instances the light is outside of (cull_signs) changes
    no texel of a map, alone or over a base, or of a face's instants splatted together: from
    outside a closed surface the nearest hit is a front face. An inward-wound instance and the
    light inside a box are handled; the sheet (open) is always kept."""
    from warp_blur.raster.culling import instance_volume_sign
    positions, tris, objects = closed_scene(5, light_inside)
    t = len(tris)
    tables = TriangleTables(tris, np.zeros(t, np.int32), np.zeros(t, np.int32), np.zeros((3 * t, 3), np.float32), "cpu")
    closed = objects != 6   # all but the sheet
    face = Face(np.eye(3), (-0.6, -0.6, 0.6, 0.6), False, 0.1) if perspective else \
        Face(np.eye(3), (-3.0, -3.0, 3.0, 3.0), True, -1e30)
    plain = FaceRasterizer(tables, tris, SIZE, "cpu")
    culling = FaceRasterizer(tables, tris, SIZE, "cpu", objects)
    samples = []
    mover = np.unique(tris[objects == 1])   # one sphere's vertices, moving over the instants
    for b in range(3):
        moved = positions.copy()
        moved[mover] += (0.3 * b, 0.0, 0.1 * b)
        samples.append(Sample(moved, np.ones(t, bool), np.zeros((0, 18), np.float32)))
    culling.object_sign = instance_volume_sign(np.stack([s.positions for s in samples]), tris, objects, closed,
                                               -np.inf, np.inf)
    assert (culling.object_sign[:6] != 0).all() and culling.object_sign[2] == -culling.object_sign[0]
    signs = culling.cull_signs(positions[None], [0], face).numpy()
    assert (signs[objects == 6] == 0).all() and (signs[objects < 6] != 0).all()
    if light_inside:
        assert (signs[objects == 7] == 0).all() == perspective   # a distant light is outside the box
    a, shift = np.eye(3), np.zeros(3)
    base = plain.depth_over(a, shift, face, samples[0], objects != 1, None, 1)
    assert np.isfinite(base).mean() > 0.2   # the scene really covers the face
    for s in samples:
        np.testing.assert_array_equal(culling.depth_over(a, shift, face, s, None, None, 2),
                                      plain.depth_over(a, shift, face, s, None, None, 2))
        np.testing.assert_array_equal(culling.depth_over(a, shift, face, s, objects == 1, base, 1),
                                      plain.depth_over(a, shift, face, s, objects == 1, base, 1))
    together = []
    for raster in (plain, culling):
        prepared = raster.instants_geometry([(a, shift)] * 3, samples, [0, 1, 2], 3, None, face)
        target = wp.array(np.repeat(base[..., None], 3, axis=2).ravel(), dtype=float, device="cpu")
        raster.splat_instants(face, prepared, 3, target, raster.no_flags, 2)
        together.append(target.numpy())
    np.testing.assert_array_equal(together[0], together[1])
    if light_inside and perspective:
        return   # the box around the light hides the rest (its inner walls are kept: maps equal)
    # the signs are what the splat reads: flipped, the front faces go and the far sides show
    culling.object_sign = -culling.object_sign
    farther = culling.depth_over(a, shift, face, samples[0], None, None, 1) > plain.depth_over(a, shift, face,
                                                                                                samples[0], None, None, 1)
    assert farther.mean() > 0.05


def numpy_still_triangles(probes: list[Sample], row: int, tri_vertices: np.ndarray) -> np.ndarray:
    """still_triangles as NumPy passes over every vertex (its form before the kernel): the oracle."""
    ref = probes[0]
    still_t = np.ones(len(tri_vertices), bool)
    origin, axes = light_frame(ref.lights[row])
    local0 = (ref.positions - origin) @ axes.T
    tol = STILL_TOL * (float(np.abs(local0).max(initial=0.0)) + 1.0)
    still_v = np.ones(len(local0), bool)
    for p in probes[1:]:
        if p.positions.shape != ref.positions.shape:
            still_v[:] = False
            break
        origin, axes = light_frame(p.lights[row])
        with np.errstate(invalid="ignore"):   # (the NaN and inf vertices)
            still_v &= (np.abs((p.positions - origin) @ axes.T - local0) <= tol).all(axis=1)
        if len(p.tri_visible) == len(still_t):
            still_t &= p.tri_visible == ref.tri_visible
    return still_t & still_v[tri_vertices].all(axis=1) if len(tri_vertices) else still_t


@pytest.mark.parametrize("seed", range(6))
def test_still_triangles_equal_numpys_passes(seed):
    """The kernel's verdicts equal NumPy's on random scenes: a moving camera and light, vertices
    moved in the world by far more and far less than the tolerance and by about it, triangles
    hidden at one probe, a NaN and an inf vertex, two lights (the second row judged)."""
    rng = np.random.default_rng(seed)
    n = 3000
    positions = rng.normal(size=(n, 3)) * 20.0 - (0, 0, 40)
    tris = rng.integers(0, n, (2000, 3)).astype(np.int32)
    lights = np.zeros((2, 18), np.float32)
    lights[:, 4:7] = rng.normal(size=(2, 3)) * 10
    for j in range(2):
        q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        lights[j, 7:10], lights[j, 10:13], lights[j, 13:16] = q[2], q[0], q[1]
    extent = np.abs(positions).max() + 50
    probes = []
    for k in range(7):
        shift = rng.normal(size=3) * (k > 0)
        p = positions + shift
        rows = lights.copy()
        rows[:, 4:7] += shift
        moved = rng.random(n) < 0.05
        p[moved] += rng.normal(size=(int(moved.sum()), 3)) * rng.choice([1e-9, 1e-5, 1.0]) * extent
        if k == 4 and seed % 2 == 0:
            p[7] = np.nan
            p[8] = np.inf
        visible = np.ones(len(tris), bool)
        if k == 5:
            visible[rng.random(len(tris)) < 0.01] = False
        probes.append(Sample(p, visible, rows))
    for row in (0, 1):
        expected = numpy_still_triangles(probes, row, tris)
        assert 0 < expected.sum() < len(tris)
        np.testing.assert_array_equal(still_triangles(probes, row, tris, threads=2), expected)
    short = [probes[0], Sample(positions[:-1], probes[1].tri_visible, lights)]
    assert not still_triangles(short, 0, tris).any()


def test_face_positions_equal_numpys_product_in_float32():
    """vertex_passes.face_positions: row b of the (times, V) float32 array is positions @ A.T + t
    as NumPy computes it in float64 and rounds to float32 (to float32's last place: the kernel may
    fuse a multiply and an add); rows not asked for are 0."""
    from warp_blur.shadows.vertex_passes import face_positions
    rng = np.random.default_rng(3)
    samples, transforms = [], []
    for k in range(2):
        positions = rng.normal(size=(20_000 + k, 3)) * 50.0
        samples.append(Sample(positions, np.ones(0, bool), np.zeros((0, 18), np.float32)))
        q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        transforms.append((q * rng.uniform(0.5, 2.0), rng.normal(size=3) * 10.0))
    out = face_positions(transforms, samples, [3, 1], 4, threads=2).numpy()
    assert out.shape == (4, 20_001, 3) and out.dtype == np.float32
    for (a, t), s, row in zip(transforms, samples, [3, 1]):
        want = (s.positions @ a.T + t).astype(np.float32)
        np.testing.assert_allclose(out[row, :len(want)], want, rtol=2e-7, atol=1e-5)
    assert not out[0].any() and not out[2].any() and not out[3, 20_000].any()
