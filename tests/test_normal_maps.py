"""Tangent-space normal maps (UsdPreviewSurface `normal` from a UsdUVTexture, scale 2, bias -1):
a constant map tilting the normal by θ towards +s or +t shades a flat Lambert quad as cos of the
angle between the tilted normal and a distant light, in every method."""

import os

import numpy as np
import pytest
from authoring import add_camera, add_distant_light, add_material, add_quad, new_stage, set_st
from PIL import Image
from pxr import Gf, Sdf, UsdShade

import warp_blur as wb

W, H = 32, 24
TILT = np.degrees(np.arctan2(0.6, 0.8))   # the map's normal (0.6, 0, 0.8): θ = 36.87°


def _stage(path: str, tilt_axis: str | None, light_rotate) -> str:
    """A white Lambert quad facing the camera (s along +x, t along +y), a distant light, and a
    constant normal map tilted towards +s ("s") or +t ("t"), or none."""
    stage = new_stage(path)
    add_camera(stage, translate=(0, 0, 8), shutter=(0.0, 0.0))
    add_distant_light(stage, "/World/Sun", intensity=2.0, rotate=light_rotate)
    mat = add_material(stage, "/World/Looks/White", diffuse=(0.8, 0.8, 0.8), roughness=1.0)
    if tilt_axis is not None:
        code = (204, 128, 230) if tilt_axis == "s" else (128, 204, 230)
        Image.fromarray(np.full((4, 4, 3), code, np.uint8)).save(os.path.join(os.path.dirname(path), "n.png"))
        surface = UsdShade.Shader.Get(stage, "/World/Looks/White/PreviewSurface")
        reader = UsdShade.Shader.Define(stage, "/World/Looks/White/St")
        reader.CreateIdAttr("UsdPrimvarReader_float2")
        reader.CreateInput("varname", Sdf.ValueTypeNames.Token).Set("st")
        tex = UsdShade.Shader.Define(stage, "/World/Looks/White/Normal")
        tex.CreateIdAttr("UsdUVTexture")
        tex.CreateInput("file", Sdf.ValueTypeNames.Asset).Set("./n.png")
        tex.CreateInput("sourceColorSpace", Sdf.ValueTypeNames.Token).Set("raw")
        tex.CreateInput("scale", Sdf.ValueTypeNames.Float4).Set(Gf.Vec4f(2, 2, 2, 1))
        tex.CreateInput("bias", Sdf.ValueTypeNames.Float4).Set(Gf.Vec4f(-1, -1, -1, 0))
        tex.CreateInput("st", Sdf.ValueTypeNames.Float2).ConnectToSource(reader.ConnectableAPI(), "result")
        tex.CreateOutput("rgb", Sdf.ValueTypeNames.Float3)
        surface.CreateInput("normal", Sdf.ValueTypeNames.Normal3f).ConnectToSource(tex.ConnectableAPI(), "rgb")
    quad = add_quad(stage, "/World/Quad", 2.0, 1.5, material=mat, translate=(0, 0, 0))
    set_st(quad, [(0, 0), (1, 0), (1, 1), (0, 1)])
    stage.GetRootLayer().Save()
    return path


def _centre(path: str, method: str) -> float:
    r = wb.render(path, frame=1, method=method, samples=1, resolution=(W, H), shadows="off")
    return float(r.rgba[H // 2 - 2:H // 2 + 2, W // 2 - 2:W // 2 + 2, 0].mean())


@pytest.mark.parametrize("method", ["accumulation", "stochastic", "analytic", "velocity"])
def test_a_normal_map_tilts_the_shading_normal_towards_s_and_t(scene_path, method):
    plain = _centre(_stage(scene_path(), None, (0, 0, 0)), method)
    assert plain > 0.05
    cases = [("s", (0, 0, 0), 0.8),             # light along the geometric normal: cos θ
             ("s", (0, TILT, 0), 1.0),          # light tilted towards +s: along the mapped normal
             ("s", (0, -TILT, 0), 0.28),        # towards -s: cos 2θ
             ("t", (-TILT, 0, 0), 1.0),         # light tilted towards +t
             ("t", (TILT, 0, 0), 0.28)]
    for axis, rotate, expected in cases:
        got = _centre(_stage(scene_path(), axis, rotate), method) / plain
        assert got == pytest.approx(expected, abs=0.015), (axis, rotate)
