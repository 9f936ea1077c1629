"""Hostile input (issue 17): non-finite material and light inputs fall back to USD's values with
a warning, so no NaN reaches a pixel."""

from __future__ import annotations

import numpy as np
import pytest

import warp_blur as wb
from warp_blur import log

STAGE = """#usda 1.0
(
    startTimeCode = 1
    endTimeCode = 1
    upAxis = "Y"
)
def Xform "World"
{
    def Camera "Cam"
    {
        double3 xformOp:translate = (0, 0, 5)
        uniform token[] xformOpOrder = ["xformOp:translate"]
    }
    def DistantLight "Sun"
    {
        color3f inputs:color = LIGHT_COLOR
        float inputs:intensity = LIGHT_INTENSITY
    }
    def Mesh "Quad" (prepend apiSchemas = ["MaterialBindingAPI"])
    {
        int[] faceVertexCounts = [4]
        int[] faceVertexIndices = [0, 1, 2, 3]
        point3f[] points = [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)]
        rel material:binding = </World/Mat>
    }
    def Material "Mat"
    {
        token outputs:surface.connect = </World/Mat/Surface.outputs:surface>
        def Shader "Surface"
        {
            uniform token info:id = "UsdPreviewSurface"
            color3f inputs:diffuseColor = DIFFUSE
            float inputs:roughness = ROUGHNESS
            token outputs:surface
        }
    }
}
"""

CASES = {"diffuse_nan": dict(DIFFUSE="(nan, 0.5, 0.5)"), "roughness_nan": dict(ROUGHNESS="nan"),
         "light_color_nan": dict(LIGHT_COLOR="(nan, 0, 0)"), "light_intensity_inf": dict(LIGHT_INTENSITY="inf")}


@pytest.mark.parametrize("case", sorted(CASES))
@pytest.mark.parametrize("method", ["analytic", "accumulation"])
def test_non_finite_inputs_fall_back_with_a_warning(tmp_path, case, method):
    values = dict(DIFFUSE="(0.5, 0.5, 0.5)", ROUGHNESS="0.5", LIGHT_COLOR="(1, 1, 1)", LIGHT_INTENSITY="2")
    values.update(CASES[case])
    text = STAGE
    for key, value in values.items():
        text = text.replace(key, value)
    path = tmp_path / "stage.usda"
    path.write_text(text)
    log.reset()   # warnings are said once per process and prim
    result = wb.render(str(path), frame=1, method=method, resolution=(32, 24), samples=2)
    assert np.isfinite(result.rgba).all()
    assert result.rgba[12, 16, :3].max() > 0.01      # the quad is lit, not black
    assert any("not a finite" in w for w in result.stats["warnings"]), result.stats["warnings"]
