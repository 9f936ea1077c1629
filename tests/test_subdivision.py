"""Catmull-Clark refinement of subdivision meshes (issue 19): the stencil follows the scheme's
rules (checked by hand on a cube), refined meshes render rounder than their cage, in every method,
and carry their primvars."""

import numpy as np
import pytest
from pxr import Gf, UsdGeom, Vt

import warp_blur as wb
from warp_blur.usd.subdivision import _one_level, refine

CUBE_POINTS = np.array([(x, y, z) for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], np.float64)
CUBE_FACES = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]]


def test_one_level_on_a_cube_follows_the_rules():
    stencil, quads, _ = _one_level([np.array(f) for f in CUBE_FACES], 8)
    refined = stencil @ CUBE_POINTS
    assert refined.shape == (8 + 12 + 6, 3) and quads.shape == (24, 4)
    # vertex points: (Q + 2R + (n - 3) P) / n with n = 3 -> 5/9 of each corner
    np.testing.assert_allclose(np.abs(refined[:8]), 5.0 / 9.0)
    # edge points: (a + b + F1 + F2) / 4 -> (0.75, 0.75, 0) up to signs and axes
    np.testing.assert_allclose(np.sort(np.abs(refined[8:20]), axis=1), np.tile([0.0, 0.75, 0.75], (12, 1)))
    # face points: centroids
    np.testing.assert_allclose(np.sort(np.abs(refined[20:]), axis=1), np.tile([0.0, 0.0, 1.0], (6, 1)))
    ref = refine(np.full(6, 4), np.concatenate(CUBE_FACES), 8, 2)
    assert ref.levels == 2 and len(ref.quads) == 96
    assert np.allclose(np.asarray(ref.stencil.sum(axis=1)).ravel(), 1.0)   # affine: rows sum to 1


def _cube_stage(path: str, scheme: str, moving: bool = False) -> str:
    from authoring import add_camera, new_stage
    stage = new_stage(path)
    add_camera(stage)
    mesh = UsdGeom.Mesh.Define(stage, "/World/Cube")
    mesh.CreatePointsAttr(Vt.Vec3fArray([Gf.Vec3f(*p) for p in CUBE_POINTS]))
    mesh.CreateFaceVertexCountsAttr([4] * 6)
    mesh.CreateFaceVertexIndicesAttr([i for f in CUBE_FACES for i in f])
    mesh.CreateSubdivisionSchemeAttr(scheme)
    colors = [Gf.Vec3f(1, 0, 0), Gf.Vec3f(0, 1, 0), Gf.Vec3f(0, 0, 1), Gf.Vec3f(1, 1, 0), Gf.Vec3f(0, 1, 1),
              Gf.Vec3f(1, 0, 1)]
    pv = UsdGeom.PrimvarsAPI(mesh).CreatePrimvar("displayColor", Sdf_color3f(), UsdGeom.Tokens.uniform)
    pv.Set(Vt.Vec3fArray(colors))
    xf = mesh.AddRotateXYZOp()
    if moving:
        xf.Set(Gf.Vec3f(20, 30, 0), 0.5)
        xf.Set(Gf.Vec3f(20, 60, 0), 1.5)
    else:
        xf.Set(Gf.Vec3f(20, 30, 0))
    stage.GetRootLayer().Save()
    return path


def Sdf_color3f():
    from pxr import Sdf
    return Sdf.ValueTypeNames.Color3fArray


def test_a_subdivided_cube_renders_rounder_than_its_cage(scene_path):
    cage = wb.render(_cube_stage(scene_path(), "none"), frame=1, method="velocity", resolution=(64, 48),
                     shadows="off").rgba[..., 3].sum()
    smooth = wb.render(_cube_stage(scene_path(), "catmullClark"), frame=1, method="velocity", resolution=(64, 48),
                       shadows="off").rgba[..., 3].sum()
    # the limit surface lies well inside the cage: through its faces' middles (~0.8 of the way to a
    # face's centre), far from its corners
    assert 0.3 * cage < smooth < 0.8 * cage


@pytest.mark.parametrize("method", ["analytic", "accumulation", "stochastic", "velocity"])
def test_a_moving_subdivided_mesh_renders_in_every_method(scene_path, method):
    from warp_blur.usd.scene import Scene
    from warp_blur.usd.stage import Shutter, choose_camera, open_stage
    path = _cube_stage(scene_path(), "catmullClark", moving=True)
    stage = open_stage(path)
    scene = Scene(stage, choose_camera(stage, None), 1.0, Shutter(0.5, 1.5))
    assert scene.num_triangles == 2 * 96
    # uniform displayColor: every refined triangle keeps its cage face's colour
    assert {tuple(np.round(c, 3)) for c in scene.corner_colors} <= {(1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 0),
                                                                     (0, 1, 1), (1, 0, 1)}
    result = wb.render(path, frame=1, method=method, resolution=(64, 48), samples=4, shadows="off")
    assert np.isfinite(result.rgba).all() and result.rgba[..., 3].max() > 0.9
