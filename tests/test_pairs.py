"""Lights whose shadows can fall on nothing lit go without maps (shadows/pairs.py)."""

from __future__ import annotations

import os

import numpy as np
import pytest

import warp_blur as wb
from warp_blur.output.metrics import max_abs
from warp_blur.shadows.layout import Sample
from warp_blur.shadows.pairs import is_convex_solid, light_shadows_nothing
from warp_blur.usd.lights import DISTANT, LIGHT_WIDTH, SPHERE

from conftest import SCENES
from scenes import lit_stage

# a unit cube's 8 corners and 12 outward triangles
CORNERS = np.array([(x, y, z) for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)], np.float64)
QUADS = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
CUBE_TRIS = np.array([t for a, b, c, d in QUADS for t in ((a, b, c), (a, c, d))], np.int64)


def light_row(kind: int = DISTANT) -> np.ndarray:
    """A light shining straight down (-y): across its beam lie x and z."""
    row = np.zeros(LIGHT_WIDTH, np.float32)
    row[0] = kind
    row[7:10] = (0, -1, 0)
    row[10:13] = (1, 0, 0)
    row[13:16] = (0, 0, 1)
    row[17] = 1
    return row


def cubes(*centres) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(positions, tri_vertices, tri_object) of unit cubes at the centres, one object each."""
    pos = np.concatenate([CORNERS + np.asarray(c, np.float64) for c in centres])
    tris = np.concatenate([CUBE_TRIS + 8 * i for i in range(len(centres))])
    return pos, tris, np.repeat(np.arange(len(centres)), len(CUBE_TRIS))


def knots_of(*positions, rows=None) -> list[Sample]:
    rows = rows or [light_row()] * len(positions)
    return [Sample(p, np.ones(12 * (len(p) // 8), bool), r[None]) for p, r in zip(positions, rows)]


def shadows_nothing(knots, tris, objects, receives=None, safe=None) -> bool:
    t = len(tris)
    return light_shadows_nothing(0, knots, tris, objects, np.ones(t, bool) if receives is None else receives,
                                 np.ones(t, bool) if safe is None else safe)


def test_a_cube_is_a_convex_solid_and_a_dented_one_is_not():
    assert is_convex_solid(CORNERS, CUBE_TRIS)
    dented = CORNERS.copy()
    dented[7] = (0.2, 0.2, 0.2)   # one corner pushed inside: the surface folds in
    assert not is_convex_solid(dented, CUBE_TRIS)
    assert not is_convex_solid(np.full_like(CORNERS, np.nan), CUBE_TRIS)
    # hostile sizes: its own scale, no overflow (1e300² is not a float)
    assert is_convex_solid(CORNERS * 1e300, CUBE_TRIS) and is_convex_solid(CORNERS * 1e-300, CUBE_TRIS)
    assert not is_convex_solid(CORNERS * np.inf, CUBE_TRIS)
    with np.errstate(over="ignore"):
        huge = CORNERS * 1e300 * 1e10   # overflows to inf
    assert not is_convex_solid(huge, CUBE_TRIS)


def test_cubes_side_by_side_under_the_sun_shadow_nothing():
    pos, tris, obj = cubes((0, 0, 0), (3, 0, 0))
    assert shadows_nothing(knots_of(pos), tris, obj)


def test_a_cube_above_another_may_shadow_it():
    pos, tris, obj = cubes((0, 0, 0), (0.4, 3, 0.2))
    assert not shadows_nothing(knots_of(pos), tris, obj)


def test_a_caster_passing_over_mid_shutter_is_caught_at_the_knots():
    """B flies over A from x = 3 to x = -3 at height 3: apart at shutter open and close, over A in
    between. The outlines are taken over every knot (and the knots' extents hold the path between
    them), so both the three knots and the two ends alone keep the maps."""
    ends = [cubes((0, 0, 0), (x, 3, 0))[0] for x in (3, 0, -3)]
    _, tris, obj = cubes((0, 0, 0), (0, 0, 0))
    assert not shadows_nothing(knots_of(*ends), tris, obj)
    assert not shadows_nothing(knots_of(ends[0], ends[2]), tris, obj)
    assert shadows_nothing(knots_of(ends[0], cubes((0, 0, 0), (3, 3, 0.5))[0]), tris, obj)


def test_a_vertex_shared_by_two_objects_bounds_both():
    """An emissive sliver (object 1) leaning on the cube's corner (0.5, 0.5, 0.5) (object 0's vertex
    7, shared), under a slanted light across whose beam that corner alone is the cube's extreme
    along x + y': the outlines touch there, so the sliver may shadow the cube. Were the corner
    counted for the sliver only, the cube's outline would end short of it (fails so)."""
    row = light_row()
    row[13:16] = (0, 0.6, 0.8)   # across the beam: x and y' = 0.6 y + 0.8 z
    pos = np.concatenate([CORNERS, [(1.5, 0.5, 1.5), (1.5, 0.6, 1.5)]])
    tris = np.concatenate([CUBE_TRIS, [(7, 8, 9)]])
    obj = np.array([0] * 12 + [1])
    knots = [Sample(pos, np.ones(13, bool), row[None])]
    assert not shadows_nothing(knots, tris, obj, receives=obj == 0)
    # the same sliver off the corner, on vertices of its own: apart
    apart = np.concatenate([CORNERS, [(2.5, 0.5, 2.5), (2.5, 0.6, 2.5), (2.6, 0.5, 2.5)]])
    tris_apart = np.concatenate([CUBE_TRIS, [(8, 9, 10)]])
    assert shadows_nothing([Sample(apart, np.ones(13, bool), row[None])], tris_apart, obj, receives=obj == 0)


def test_nothing_lit_means_nothing_to_shadow():
    pos, tris, obj = cubes((0, 0, 0), (0, 3, 0))
    assert shadows_nothing(knots_of(pos), tris, obj, receives=np.zeros(len(tris), bool))
    # only the top cube is lit: the one below it may still shadow it (no depth test: conservative)
    assert not shadows_nothing(knots_of(pos), tris, obj, receives=obj == 1)


def test_a_receiver_that_may_shadow_itself_keeps_the_maps():
    pos, tris, obj = cubes((0, 0, 0))
    assert shadows_nothing(knots_of(pos), tris, obj)
    assert not shadows_nothing(knots_of(pos), tris, obj, safe=np.zeros(len(tris), bool))   # smooth or open
    dented = pos.copy()
    dented[7] = (0.2, 0.2, 0.2)
    assert not shadows_nothing(knots_of(dented), tris, obj)
    assert not shadows_nothing(knots_of(pos, dented, pos), tris, obj)   # folded at one knot only


def test_closed_flat_prims_without_normal_maps_are_self_safe():
    """pair_receivers: a normal map (like smooth normals) may light a face turned from the light."""
    from types import SimpleNamespace
    from warp_blur.shadows.pairs import pair_receivers
    from warp_blur.usd.materials import COL_NORMAL_BINDING, MATERIAL_WIDTH
    from warp_blur.usd.units import FLAG_SMOOTH
    table = np.zeros((3, MATERIAL_WIDTH), np.float32)
    table[:, COL_NORMAL_BINDING] = -1
    table[1:, 0:3] = 0.5            # 0 emissive-only, 1 and 2 diffuse
    table[2, COL_NORMAL_BINDING] = 0    # 2 normal-mapped
    scene = SimpleNamespace(material_table=table, tri_material=np.array([0, 1, 2, 1, 1]),
                            tri_closed=np.array([True, True, True, False, True]),
                            tri_flags=np.array([0, 0, 0, 0, FLAG_SMOOTH]))
    receives, safe = pair_receivers(scene)
    assert receives.tolist() == [False, True, True, True, True]
    assert safe.tolist() == [True, True, False, False, False]


def test_lights_that_change_or_are_local_keep_their_maps():
    pos, tris, obj = cubes((0, 0, 0), (3, 0, 0))
    turned = light_row()
    turned[10:13] = (0.8, 0.6, 0)
    assert not shadows_nothing(knots_of(pos, pos, rows=[light_row(), turned]), tris, obj)
    assert not shadows_nothing(knots_of(pos, rows=[light_row(SPHERE)]), tris, obj)


@pytest.mark.parametrize("method", ["analytic", "stochastic"])
def test_rotations_sun_shadows_nothing_so_it_gets_no_maps(method, monkeypatch):
    """rotation.usda: the blades are emissive, the box a convex flat-shaded Cube, and the blades'
    outline across the sun's beam never meets the box's: its frame renders without maps, the same
    image but where the maps' bias left the box's own faces a trace of self-shadow (measured
    3.1e-5 at 160×120)."""
    import warp_blur.shadows.pairs as pairs
    kw = dict(frame=2.0, resolution=(128, 96), method=method, samples=4, aovs=())
    path = os.path.join(SCENES, "rotation.usda")
    without = wb.render(path, **kw)
    monkeypatch.setattr(pairs, "PAIR_CULLING", False)
    with_maps = wb.render(path, **kw)
    assert without.stats["shadow_lights_unneeded"] == 1 and "shadow_lights" not in without.stats
    assert with_maps.stats["shadow_lights"] == 1 and "shadow_lights_unneeded" not in with_maps.stats
    assert max_abs(without.rgba, with_maps.rgba) <= 1e-4


def test_a_shadow_that_falls_keeps_its_maps(scene_path, monkeypatch):
    """A moving triangle's shadow on a lit quad (open, so it may shadow itself too): the maps stay
    and the image is what it was."""
    import warp_blur.shadows.pairs as pairs
    path = lit_stage(scene_path())
    kw = dict(frame=1.0, resolution=(96, 72), method="analytic", aovs=())
    culled = wb.render(path, **kw)
    monkeypatch.setattr(pairs, "PAIR_CULLING", False)
    kept = wb.render(path, **kw)
    assert culled.stats["shadow_lights_unneeded"] == 0 and culled.stats["shadow_lights"] == 1
    np.testing.assert_array_equal(culled.rgba, kept.rgba)
