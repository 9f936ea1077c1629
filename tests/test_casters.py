"""Triangles that cannot shadow anything from a light (shadows/casters.py): found exactly, kept
whenever the light or any geometry is on the other side of their plane, and left out of the maps
without changing the image."""

from __future__ import annotations

import numpy as np
import pytest
from scenes import shadow_stage

import warp_blur as wb
from warp_blur.shadows import casters
from warp_blur.shadows.casters import bounding_planes, non_casters
from warp_blur.shadows.layout import FAR, Face, LightLayout, Sample
from warp_blur.usd.lights import DISTANT, LIGHT_WIDTH, SPHERE

RES = (128, 96)


def box(lo, hi, inward: bool = False):
    """(8, 3) corners and (12, 3) outward-wound triangles of an axis-aligned box (inward: reversed)."""
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])], float)
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    tris = np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))])
    return corners, (tris[:, ::-1] if inward else tris)


def scene(extra_points=()):
    """A 10×10 floor (2 triangles) in the plane z = 0 and a box resting on it, in camera space."""
    floor = np.array([[-5, -5, 0], [5, -5, 0], [5, 5, 0], [-5, 5, 0]], float)
    corners, tris = box((-1, -1, 0.5), (1, 1, 1.5))
    pts = np.concatenate([floor, corners, np.reshape(np.array(extra_points, float), (-1, 3))])
    tv = np.concatenate([[[0, 1, 2], [0, 2, 3]], tris + 4])
    if len(extra_points):   # a sliver triangle through the extra points, so they are used geometry
        k = len(pts) - 1
        tv = np.concatenate([tv, [[4, 5, k]]])
    return pts, tv


def light(kind: int, origin=(0, 0, 0), axes=np.eye(3)):
    row = np.zeros((1, LIGHT_WIDTH))
    row[0, 0] = kind
    row[0, 4:7] = origin
    row[0, 10:13], row[0, 13:16] = axes[0], axes[1]
    faces = [Face(np.eye(3), (-10, -10, 10, 10), True, -FAR)] if kind == DISTANT else []
    return row, LightLayout(0, kind, np.zeros((1, 3)), faces)


def dropped(pts, tv, kind, **kw):
    row, lay = light(kind, **kw)
    s = Sample(pts, np.ones(len(tv), bool), row)
    return np.nonzero(non_casters(bounding_planes(s, tv), lay, [s], tv))[0]


def test_a_floor_under_a_lamp_cannot_cast_but_the_box_on_it_can():
    pts, tv = scene()
    assert list(dropped(pts, tv, SPHERE, origin=(0, 0, 5))) == [0, 1]


def test_a_floor_with_the_lamp_or_any_geometry_below_it_casts():
    pts, tv = scene()
    top = [12, 13]     # the box's top face: from below, all the scene lies between it and the lamp
    assert list(dropped(pts, tv, SPHERE, origin=(0, 0, -5))) == top
    assert list(dropped(pts, tv, SPHERE, origin=(3, 3, 0))) == top       # the lamp in the floor's plane: kept
    below, tv_below = scene(extra_points=[(4, 4, -0.01)])
    assert len(dropped(below, tv_below, SPHERE, origin=(0, 0, 5))) == 0


def test_a_distant_light_from_above_leaves_the_floor_out_and_from_below_keeps_it():
    pts, tv = scene()
    assert list(dropped(pts, tv, DISTANT)) == [0, 1]                     # towards the light: +z
    flipped = np.diag([1.0, -1.0, -1.0])                                 # local z = -z: light below
    assert list(dropped(pts, tv, DISTANT, axes=flipped)) == [12, 13]    # only the box's top face


def test_the_walls_of_a_room_cannot_cast_from_a_lamp_inside_it():
    corners, tris = box((-4, -4, -3), (4, 4, 3), inward=True)
    chair, chair_tris = box((-1, -1, -3), (0, 0, -2))
    pts = np.concatenate([corners, chair])
    tv = np.concatenate([tris, chair_tris + 8])
    on_floor = [12 + 8, 12 + 9]       # the chair's underside, in the floor's plane
    assert list(dropped(pts, tv, SPHERE, origin=(1, 1, 2))) == list(range(12)) + on_floor
    # from outside, beyond the wall x = 4 (triangles 2, 3): that wall stands between, the rest cannot
    assert list(dropped(pts, tv, SPHERE, origin=(6, 0, 0))) == [0, 1] + list(range(4, 12)) + on_floor


@pytest.mark.parametrize("method", ["analytic", "stochastic", "accumulation"])
def test_leaving_the_floor_out_of_a_moving_lamps_maps_changes_no_pixel(scene_path, monkeypatch, method):
    """A moving sphere light over the ground and a moving occluder: the ground's two triangles are
    left out of every map, and the image is the one with them in."""
    path = shadow_stage(scene_path(), occluder_samples={0.5: (-1.0, 1.0, 0.0), 1.5: (1.0, 1.0, 0.0)},
                        light="sphere", light_size=0.2, light_samples={0.5: (-0.3, 3, 0), 1.5: (0.3, 3, 0)})
    kw = {} if method == "analytic" else {"samples": 16}
    out = wb.render(path, frame=1, method=method, resolution=RES, shadow_map_size=256, aovs=(), **kw)
    assert out.stats["shadow_non_casters"] == [2]
    monkeypatch.setattr(casters, "bounding_planes", lambda *_a: [])
    full = wb.render(path, frame=1, method=method, resolution=RES, shadow_map_size=256, aovs=(), **kw)
    assert full.stats["shadow_non_casters"] == [0]
    assert np.abs(out.rgba - full.rgba).max() <= 1e-6
    off = wb.render(path, frame=1, method=method, resolution=RES, shadows="off", aovs=(), **kw)
    assert np.abs(out.rgba - off.rgba).max() > 0.03      # there is a shadow


def test_size_prefilter_keeps_the_triangles_numpy_would():
    """raster/triangle_sizes.triangles_at_least, the plane search's prefilter, against NumPy's
    cross products: the same triangles at and above a bound (far from it: rounding aside)."""
    import numpy as np
    from warp_blur.raster.triangle_sizes import triangles_at_least
    rng = np.random.default_rng(3)
    positions = rng.normal(0, 1, (3000, 3)) * np.where(rng.random((3000, 1)) < 0.5, 0.01, 1.0)
    tri_vertices = rng.integers(0, 3000, (2000, 3))
    tri_vertices[:20, 2] = tri_vertices[:20, 1]            # degenerate: zero area
    tris = np.arange(0, 2000, 3)
    a = positions[tri_vertices[tris, 0]]
    area2 = np.linalg.norm(np.cross(positions[tri_vertices[tris, 1]] - a, positions[tri_vertices[tris, 2]] - a), axis=1)
    bound = float(np.median(area2))
    want = tris[area2 >= bound]
    got = triangles_at_least(positions, tri_vertices, tris, bound)
    near = np.abs(area2 - bound) <= 1e-12 * bound
    assert 100 < len(want) < len(tris)
    assert set(got[~np.isin(got, tris[near])]) == set(want[~np.isin(want, tris[near])])
    assert len(triangles_at_least(positions, tri_vertices, tris[:0], bound)) == 0


@pytest.mark.parametrize("n", [1, 7, 70_000, 300_001])
def test_support_equals_numpys_product_max_and_first_argmax(n):
    """casters.support's kernel bands give NumPy's (DIRECTIONS @ points.T).max and .argmax
    (the first index of a tie) exactly: points on an integer grid tie often, and a far point and
    negative coordinates are in."""
    rng = np.random.default_rng(n)
    points = rng.integers(-3, 4, (n, 3)).astype(np.float64)
    points[rng.random(n) < 0.3] *= 1.37
    if n > 10:
        points[n // 2] = (1e12, -1e12, 3.0)
    proj = casters.DIRECTIONS @ points.T
    best, at = casters.support(points, threads=2)
    np.testing.assert_array_equal(best, proj.max(axis=1))
    np.testing.assert_array_equal(at, proj.argmax(axis=1))
