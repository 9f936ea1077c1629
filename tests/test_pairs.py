"""Lights whose shadows can fall on nothing lit go without maps (shadows/pairs.py)."""

from __future__ import annotations

import os

import numpy as np
import pytest

import warp_blur as wb
from warp_blur.output.metrics import max_abs
from warp_blur.shadows.layout import Sample
from warp_blur.shadows.pairs import is_convex_solid, light_shadows_nothing, may_drop_lights
from warp_blur.usd.lights import DISK, DISTANT, LIGHT_WIDTH, RECT, SPHERE

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


def test_convexity_of_many_shapes_at_once_is_each_ones():
    """(K, V, 3) shapes are checked together: convex only when every one is, each in its own scale."""
    dented = CORNERS.copy()
    dented[7] = (0.2, 0.2, 0.2)
    turned = CORNERS @ np.array([[0.6, 0.8, 0.0], [-0.8, 0.6, 0.0], [0.0, 0.0, 1.0]]) * 1e6 + 5e6
    assert is_convex_solid(np.stack([CORNERS, turned, CORNERS * 1e-300]), CUBE_TRIS)
    assert not is_convex_solid(np.stack([CORNERS, turned, dented]), CUBE_TRIS)
    assert not is_convex_solid(np.stack([CORNERS, np.full_like(CORNERS, np.nan)]), CUBE_TRIS)
    assert not is_convex_solid(np.stack([CORNERS, CORNERS * 0.0]), CUBE_TRIS)   # one shape of no size
    # beyond MAX_CONVEX_WORK over all shapes: not checked, not convex
    many = np.repeat(CORNERS[None], 4_000_000 // (len(CUBE_TRIS) * 8) + 1, axis=0)
    assert not is_convex_solid(many, CUBE_TRIS)


def test_cubes_side_by_side_under_the_sun_shadow_nothing():
    pos, tris, obj = cubes((0, 0, 0), (3, 0, 0))
    assert shadows_nothing(knots_of(pos), tris, obj)


def test_a_cube_above_another_may_shadow_it():
    pos, tris, obj = cubes((0, 0, 0), (0.4, 3, 0.2))
    assert not shadows_nothing(knots_of(pos), tris, obj)


@pytest.mark.parametrize("chunk", [None, 1])
def test_a_caster_passing_over_mid_shutter_is_caught_at_the_knots(chunk, monkeypatch):
    """B flies over A from x = 3 to x = -3 at height 3: apart at shutter open and close, over A in
    between. The outlines are taken over every knot (and the knots' extents hold the path between
    them), so both the three knots and the two ends alone keep the maps; the same with the
    extents projected a knot at a time (EXTENT_CHUNK)."""
    if chunk is not None:
        import warp_blur.shadows.pairs as pairs
        monkeypatch.setattr(pairs, "EXTENT_CHUNK", chunk)
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


def test_lights_may_be_dropped_only_where_no_lit_surface_may_shadow_itself():
    """may_drop_lights: the pre-check before accumulation keeps every instant as a knot."""
    receives = np.array([True, True, False])
    safe = np.array([True, False, False])
    assert not may_drop_lights(np.ones(3, bool), receives, safe)             # the second may shadow itself
    assert may_drop_lights(np.array([True, False, True]), receives, safe)    # ... unless it is not seen
    assert not may_drop_lights(np.zeros(0, bool), receives, safe)            # no visibility given: all seen


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


def test_lights_that_change_keep_their_maps():
    pos, tris, obj = cubes((0, 0, 0), (3, 0, 0))
    turned = light_row()
    turned[10:13] = (0.8, 0.6, 0)
    assert not shadows_nothing(knots_of(pos, pos, rows=[light_row(), turned]), tris, obj)


def lamp(kind: int = SPHERE, at=(0, 5, 0), radius: float = 0.0) -> np.ndarray:
    row = light_row(kind)
    row[4:7] = at
    row[16] = radius
    return row


def test_a_lamp_above_cubes_side_by_side_shadows_nothing():
    """From a point lamp at (0, 5, 0) the cube at x = 4 sits in no other cube's shadow volume: a
    plane along one of the 13 directions parts each caster from the hull of the receiver and the
    lamp (here x + y parts the cube under the lamp from the far cube's hull)."""
    pos, tris, obj = cubes((0, 0, 0), (4, 0, 0))
    assert shadows_nothing(knots_of(pos, rows=[lamp()]), tris, obj)


def test_a_cube_between_the_lamp_and_another_may_shadow_it():
    pos, tris, obj = cubes((0, 0, 0), (4, 0, 0), (0.2, 2.5, 0.1))
    assert not shadows_nothing(knots_of(pos, rows=[lamp()]), tris, obj)


def test_an_area_lights_reach_counts():
    """The same cubes under a sphere, disk or rect light whose samples reach 5 units from its centre:
    the hull of the far cube and the light meets the near cube, so the maps stay (conservative: a
    light's sample points lie anywhere within its reach)."""
    pos, tris, obj = cubes((0, 0, 0), (4, 0, 0))
    assert not shadows_nothing(knots_of(pos, rows=[lamp(radius=5.0)]), tris, obj)
    disk = lamp(DISK)
    disk[10:13] = (5, 0, 0)
    assert not shadows_nothing(knots_of(pos, rows=[disk]), tris, obj)
    rect = lamp(RECT)
    rect[10:13], rect[13:16] = (3, 0, 0), (0, 0, 4)   # half-diagonal 5
    assert not shadows_nothing(knots_of(pos, rows=[rect]), tris, obj)
    small = lamp(RECT)
    small[10:13], small[13:16] = (0.3, 0, 0), (0, 0, 0.4)
    assert shadows_nothing(knots_of(pos, rows=[small]), tris, obj)


def culled_and_kept(path: str, monkeypatch, **kw):
    """Renders of path without the maps of lights that shadow nothing, and with every light's."""
    import warp_blur.shadows.pairs as pairs
    culled = wb.render(path, aovs=(), **kw)
    monkeypatch.setattr(pairs, "PAIR_CULLING", False)
    return culled, wb.render(path, aovs=(), **kw)


@pytest.mark.parametrize("method", ["analytic", "stochastic", "velocity", "accumulation"])
def test_rotations_sun_shadows_nothing_so_it_gets_no_maps(method, monkeypatch):
    """rotation.usda: the blades are emissive, the box a convex flat-shaded Cube, and the blades'
    outline across the sun's beam never meets the box's: its frame renders without maps, the same
    image but where the maps' bias left the box's own faces a trace of self-shadow (measured
    3.1e-5 at 160×120). The velocity method's knots are the scene at open, centre and close, all
    it shades (session 67: its maps were 30% of its frame here); accumulation's are its instants
    (session 70)."""
    without, with_maps = culled_and_kept(os.path.join(SCENES, "rotation.usda"), monkeypatch, frame=2.0,
                                         resolution=(128, 96), method=method, samples=4)
    assert without.stats["shadow_lights_unneeded"] == 1 and "shadow_lights" not in without.stats
    assert with_maps.stats["shadow_lights"] == 1 and "shadow_lights_unneeded" not in with_maps.stats
    assert max_abs(without.rgba, with_maps.rgba) <= 1e-4


def cubes_under_a_lamp_stage(path: str) -> str:
    """Two lit Cubes side by side (one sliding), under a small sphere light between and above
    them, no ground: from the lamp neither can come between it and the other."""
    from authoring import add_camera, add_dome, add_material, add_sphere_light, add_xform_ops, new_stage
    from pxr import UsdGeom, UsdShade
    stage = new_stage(path)
    add_camera(stage)
    add_dome(stage)
    add_sphere_light(stage, "/World/Lamp", radius=0.1, intensity=40.0, translate=(0, 4, 2))
    grey = add_material(stage, "/World/Looks/Grey", diffuse=(0.6, 0.6, 0.6), roughness=0.5)
    for name, at, samples in (("A", (-2, 0, 0), {0.5: (-2.3, 0, 0), 1.5: (-1.7, 0, 0)}), ("B", (2, 0, 0), None)):
        cube = UsdGeom.Cube.Define(stage, f"/World/{name}")
        add_xform_ops(cube, translate=None if samples else at, translate_samples=samples)
        UsdShade.MaterialBindingAPI.Apply(cube.GetPrim()).Bind(grey)
    stage.GetRootLayer().Save()
    return path


@pytest.mark.parametrize("method", ["analytic", "accumulation"])
def test_a_lamp_over_cubes_apart_gets_no_maps(scene_path, monkeypatch, method):
    """The lamp's maps are not built, and the image is the one with them but for their own
    self-shadow trace on the cubes' lit faces, which only ever darkened: without the maps no pixel
    is darker, and a few at the faces' edges are brighter (measured: 42 of 6912 pixels, by at most
    1.0e-3 at 96×72; direct maps draw the same trace)."""
    culled, kept = culled_and_kept(cubes_under_a_lamp_stage(scene_path()), monkeypatch, frame=1.0,
                                   resolution=(96, 72), method=method)
    assert culled.stats["shadow_lights_unneeded"] == 1 and kept.stats["shadow_lights"] == 1
    if method == "accumulation":   # every instant's positions beyond their memory share: the maps stay
        import warp_blur.methods.accumulation as accumulation
        import warp_blur.shadows.pairs as pairs
        monkeypatch.setattr(accumulation, "KNOT_BUDGET_SHARE", 0.0)
        monkeypatch.setattr(pairs, "PAIR_CULLING", True)
        over = wb.render(cubes_under_a_lamp_stage(scene_path()), aovs=(), frame=1.0, resolution=(96, 72), method=method)
        assert over.stats["shadow_lights"] == 1 and "shadow_lights_unneeded" not in over.stats
        np.testing.assert_array_equal(over.rgba, kept.rgba)
    lighter = culled.rgba[..., :3] - kept.rgba[..., :3]
    assert lighter.min() >= -1e-6 and lighter.max() <= 2e-3
    assert (np.abs(lighter).max(axis=-1) > 1e-4).mean() < 0.01


@pytest.mark.parametrize("method", ["analytic", "velocity", "accumulation"])
def test_a_shadow_that_falls_keeps_its_maps(scene_path, monkeypatch, method):
    """A moving triangle's shadow on a lit quad (open, so it may shadow itself too): the maps stay
    and the image is what it was (accumulation does not even keep its instants as knots: the lit
    quad may shadow itself, so no light could be dropped)."""
    culled, kept = culled_and_kept(lit_stage(scene_path()), monkeypatch, frame=1.0, resolution=(96, 72),
                                   method=method)
    assert culled.stats.get("shadow_lights_unneeded", 0) == 0 and culled.stats["shadow_lights"] == 1
    assert ("shadow_lights_unneeded" in culled.stats) == (method != "accumulation")
    np.testing.assert_array_equal(culled.rgba, kept.rgba)
