"""UsdSkel-skinned meshes move as USD's own skinning computes them, for every method."""

import os
import shutil

import numpy as np
import pytest
from conftest import SCENES
from pxr import Gf, Usd, UsdGeom, UsdSkel

import warp_blur as wb
from warp_blur.usd.scene import Scene
from warp_blur.usd.stage import Shutter, choose_camera, open_stage

SKINNED = os.path.join(SCENES, "skinned.usda")


def test_skinned_points_match_usd_bake_skinning(tmp_path):
    stage = open_stage(SKINNED)
    scene = Scene(stage, choose_camera(stage, None), 5.0, Shutter(4.75, 5.25))
    unit = next(i for i, u in enumerate(scene.units) if u.path == "/World/Arm/Mesh")
    copy = str(tmp_path / "baked.usda")  # a separate layer: baking edits the stage it is given
    shutil.copy(SKINNED, copy)
    baked = Usd.Stage.Open(copy)
    assert UsdSkel.BakeSkinning(UsdSkel.Root(baked.GetPrimAtPath("/World/Arm")), Gf.Interval(1, 24))
    mesh = UsdGeom.Mesh(baked.GetPrimAtPath("/World/Arm/Mesh"))
    cam = UsdGeom.Xformable(baked.GetPrimAtPath("/World/Cam"))
    for t in (4.0, 5.0, 6.0):
        pts = np.array(mesh.GetPointsAttr().Get(t), np.float64)
        m = np.array(mesh.ComputeLocalToWorldTransform(t)) @ np.linalg.inv(np.array(cam.ComputeLocalToWorldTransform(t)))
        expect = (np.c_[pts, np.ones(len(pts))] @ m)[:, :3]
        o = scene.unit_vertex_offsets[unit]
        got = scene.snapshot(t).positions[o:o + len(pts)]
        np.testing.assert_allclose(got, expect, atol=1e-5)


@pytest.mark.parametrize("method", ["accumulation", "stochastic", "analytic", "velocity"])
def test_every_method_renders_the_skinned_arm(method):
    r = wb.render(SKINNED, frame=5, resolution=(64, 48), method=method, samples=8 if method != "analytic" else None)
    assert np.isfinite(r.rgba).all()
    assert (r.rgba[..., 3] > 0).sum() > 50
    moving = np.abs(r.aovs["motion"]).max()
    assert moving > 1.0  # the arm swings by pixels within the shutter
