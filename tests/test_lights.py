"""UsdLux lights as the spec defines them: a DistantLight's illuminance from intensity and angle."""

import math

import pytest
from authoring import add_camera, add_material, add_quad, new_stage
from pxr import UsdLux

import warp_blur as wb


@pytest.mark.parametrize("angle,normalize,expected_factor", [
    (0.53, False, math.pi * math.sin(math.radians(0.53) / 2) ** 2),   # USD's sun: E = L π sin²(angle/2)
    (10.0, False, math.pi * math.sin(math.radians(10.0) / 2) ** 2),
    (0.53, True, 1.0),                                                  # normalized: intensity is E
    (0.0, False, 1.0),                                                  # a delta light
])
def test_distant_light_illuminance_follows_usdlux(scene_path, angle, normalize, expected_factor):
    """A white Lambert quad facing a distant light head-on: radiance = albedo / π × E."""
    path = scene_path()
    stage = new_stage(path)
    add_camera(stage, shutter=(0, 0))
    light = UsdLux.DistantLight.Define(stage, "/World/Sun")
    light.CreateIntensityAttr(50000.0)
    light.CreateAngleAttr(angle)
    light.CreateNormalizeAttr(normalize)
    UsdLux.ShadowAPI.Apply(light.GetPrim()).CreateShadowEnableAttr(False)
    white = add_material(stage, "/World/Looks/White", diffuse=(1.0, 1.0, 1.0))
    add_quad(stage, "/World/Quad", 3.0, 3.0, material=white)
    stage.GetRootLayer().Save()
    r = wb.render(path, frame=1, samples=1, resolution=(16, 12))
    expected = 50000.0 * expected_factor / math.pi
    assert r.rgba[6, 8, 0] == pytest.approx(expected, rel=1e-4)


@pytest.mark.parametrize("method", ["accumulation", "stochastic", "analytic", "velocity"])
def test_single_sided_back_face_is_lit_like_a_double_sided_one(scene_path, method):
    """A quad whose front faces away from the camera, lit from the camera's side: its back face is
    shaded with the flipped normal whether or not it is double-sided (issue 19: it rendered black
    when single-sided), at albedo / π × E."""
    from pxr import UsdGeom
    pictures = []
    for double in (True, False):
        path = scene_path()
        stage = new_stage(path)
        add_camera(stage, shutter=(0, 0))
        light = UsdLux.DistantLight.Define(stage, "/World/Sun")   # shines along -Z, onto the camera's side
        light.CreateIntensityAttr(2.0)
        light.CreateNormalizeAttr(True)
        white = add_material(stage, "/World/Looks/White", diffuse=(0.5, 0.5, 0.5))
        quad = add_quad(stage, "/World/Quad", 3.0, 3.0, material=white, double_sided=double)
        UsdGeom.Mesh(quad).GetOrientationAttr().Set(UsdGeom.Tokens.leftHanded)   # front face points to -Z
        stage.GetRootLayer().Save()
        pictures.append(wb.render(path, frame=1, method=method, resolution=(16, 12), aovs=()).rgba)
    assert pictures[1][6, 8, 0] == pytest.approx(0.5 / math.pi * 2.0, rel=1e-3)
    assert abs(pictures[1] - pictures[0]).max() < 1e-5


@pytest.mark.parametrize("method", ["accumulation", "stochastic", "analytic", "velocity"])
def test_authored_normals_shade_in_every_method(scene_path, method):
    """A flat quad facing the camera and a light behind the camera, its authored normals leaning
    60° away: Lambert radiance is albedo / π × E × cos 60° (flat facets would give cos 0°)."""
    from pxr import Gf, Sdf, UsdGeom, Vt
    path = scene_path()
    stage = new_stage(path)
    add_camera(stage, shutter=(0, 0))
    light = UsdLux.DistantLight.Define(stage, "/World/Sun")   # shines along -Z
    light.CreateIntensityAttr(2.0)
    light.CreateNormalizeAttr(True)
    UsdLux.ShadowAPI.Apply(light.GetPrim()).CreateShadowEnableAttr(False)
    white = add_material(stage, "/World/Looks/White", diffuse=(0.5, 0.5, 0.5))
    quad = add_quad(stage, "/World/Quad", 3.0, 3.0, material=white)
    lean = Gf.Vec3f(math.sin(math.radians(60)), 0.0, math.cos(math.radians(60)))
    pv = UsdGeom.PrimvarsAPI(quad).CreatePrimvar("normals", Sdf.ValueTypeNames.Normal3fArray, "vertex")
    pv.Set(Vt.Vec3fArray([lean] * 4))
    stage.GetRootLayer().Save()
    r = wb.render(path, frame=1, method=method, resolution=(16, 12), aovs=())
    assert r.rgba[6, 8, 0] == pytest.approx(0.5 / math.pi * 2.0 * 0.5, rel=2e-3)


def test_light_inputs_are_read_once_unless_they_vary(scene_path):
    """A frame's motion planning builds the light table at every snapshot: a light whose inputs and
    visibility have no time samples is read once (its inputs held), a light with an animated
    intensity is read at every time, and both give the table read afresh at each time."""
    import numpy as np
    from pxr import Usd, UsdGeom
    from scenes import lit_stage, ramp_light_stage

    from warp_blur.usd.lights import find_lights, light_table
    for build, varies in ((lit_stage, False), (ramp_light_stage, True)):
        stage = Usd.Stage.Open(build(scene_path()))
        lights, _ = find_lights(stage)
        fresh = lambda: find_lights(stage)[0]   # noqa: E731
        cam = np.eye(4)
        tables = [light_table(lights, t, cam, UsdGeom.XformCache(t)) for t in (0.6, 1.0, 1.4)]
        assert lights[0].held["varies"] is varies
        assert ("inputs" in lights[0].held) is not varies
        for t, table in zip((0.6, 1.0, 1.4), tables):
            np.testing.assert_array_equal(table, light_table(fresh(), t, cam, UsdGeom.XformCache(t)))
        assert np.array_equal(tables[0], tables[2]) is not varies   # the ramp's intensity rises


def test_a_still_lights_row_is_remade_when_the_camera_or_the_light_moves(scene_path):
    """light_table keeps a light's last row while its inputs hold still and neither its transform
    nor the camera's has changed: a changed camera matrix, or a light turned between calls, gets a
    new row, equal to the table read afresh."""
    import numpy as np
    from pxr import Gf, Usd, UsdGeom
    from scenes import lit_stage

    from warp_blur.usd.lights import find_lights, light_table
    stage = Usd.Stage.Open(lit_stage(scene_path()))
    lights, _ = find_lights(stage)
    turn = np.eye(4)
    turn[:3, :3] = np.array(Gf.Matrix4d().SetRotate(Gf.Rotation(Gf.Vec3d(0, 1, 0), 30.0)).ExtractRotationMatrix())
    cams = (np.eye(4), turn, np.eye(4))
    tables = [light_table(lights, 1.0, cam, UsdGeom.XformCache(1.0)) for cam in cams]
    for cam, table in zip(cams, tables):
        np.testing.assert_array_equal(table, light_table(find_lights(stage)[0], 1.0, cam, UsdGeom.XformCache(1.0)))
    assert not np.array_equal(tables[0], tables[1]) and np.array_equal(tables[0], tables[2])
    UsdGeom.Xformable(lights[0].prim).AddRotateYOp(opSuffix="extra").Set(45.0)
    moved = light_table(lights, 1.0, cams[0], UsdGeom.XformCache(1.0))
    np.testing.assert_array_equal(moved, light_table(find_lights(stage)[0], 1.0, cams[0], UsdGeom.XformCache(1.0)))
    assert not np.array_equal(moved, tables[0])
