"""usd/values.py: an array attribute authored with a type USD does not know (`in[]
faceVertexIndices`: the fuzz soak's seed 5713 cut a byte out of `int[]`) composes and reads back as
an Sdf.UnregisteredValue. Before, the first array conversion raised TypeError inside the frame (a
failed frame, exit 1); now it is invalid geometry naming the attribute and the type authored
(exit 2), and --skip-invalid drops the prim: the frame equals the stage with the prim hidden."""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Sdf, Usd

import warp_blur as wb
from warp_blur.core import log
from warp_blur.core.errors import InvalidGeometryError
from warp_blur.usd.values import UnreadableValue, array_value, value_count

PRELUDE = """#usda 1.0
(
    startTimeCode = 1
    endTimeCode = 2
    upAxis = "Y"
)
def Xform "World"
{
    def Camera "Cam"
    {
        double3 xformOp:translate = (0, 0, 6)
        uniform token[] xformOpOrder = ["xformOp:translate"]
        double shutter:open = -0.25
        double shutter:close = 0.25
    }
    def SphereLight "Lamp"
    {
        float inputs:intensity = 30
        float inputs:radius = 0.25
        double3 xformOp:translate = (1, 2, 3)
        uniform token[] xformOpOrder = ["xformOp:translate"]
    }
    def Mesh "Back"
    {
        int[] faceVertexCounts = [4]
        int[] faceVertexIndices = [0, 1, 2, 3]
        point3f[] points = [(-4, -3, -1), (4, -3, -1), (4, 3, -1), (-4, 3, -1)]
    }
"""

MOVE = """        double3 xformOp:translate.timeSamples = {1: (-0.5, 0, 0), 2: (0.5, 0, 0)}
        uniform token[] xformOpOrder = ["xformOp:translate"]
"""

#: name -> (the target prim, the line whose type name the bad variant damages, the damaged line)
TARGETS = {
    "mesh_indices": ("""    def Mesh "Target"
    {
        int[] faceVertexCounts = [4]
        int[] faceVertexIndices = [0, 1, 2, 3]
        point3f[] points = [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)]
""" + MOVE + "    }\n", "int[] faceVertexIndices", "in[] faceVertexIndices"),
    "mesh_points": (None, "point3f[] points = [(-1", "poin3f[] points = [(-1"),
    "subdivision_creases": ("""    def Mesh "Target"
    {
        uniform token subdivisionScheme = "catmullClark"
        int[] faceVertexCounts = [4, 4]
        int[] faceVertexIndices = [0, 1, 4, 3, 1, 2, 5, 4]
        point3f[] points = [(-1, -1, 0), (0, -1, 0), (1, -1, 0), (-1, 1, 0), (0, 1, 0), (1, 1, 0)]
        int[] creaseIndices = [1, 4]
        int[] creaseLengths = [2]
        float[] creaseSharpnesses = [3]
""" + MOVE + "    }\n", "int[] creaseIndices", "ints[] creaseIndices"),
    "points": ("""    def Points "Target"
    {
        point3f[] points = [(-1, 0, 0), (0, 0.5, 0), (1, 0, 0)]
        float[] widths = [0.5, 0.5, 0.5]
""" + MOVE + "    }\n", "point3f[] points = [(-1, 0", "pt3f[] points = [(-1, 0"),
    "curves": ("""    def BasisCurves "Target"
    {
        uniform token type = "linear"
        int[] curveVertexCounts = [3]
        point3f[] points = [(-1, 0, 0), (0, 1, 0), (1, 0, 0)]
        float[] widths = [0.2]
        uniform token widthsInterpolation = "constant"
""" + MOVE + "    }\n", "int[] curveVertexCounts", "int32[] curveVertexCounts"),
    "instancer": ("""    def PointInstancer "Target"
    {
        rel prototypes = </World/Target/Proto>
        int[] protoIndices = [0, 0]
        point3f[] positions = [(-1, 0, 0), (1, 0, 0)]
""" + MOVE + """        def Cube "Proto"
        {
            double size = 0.8
        }
    }
""", "int[] protoIndices", "i[] protoIndices"),
}
TARGETS["mesh_points"] = (TARGETS["mesh_indices"][0],) + TARGETS["mesh_points"][1:]
TARGETS["points_widths"] = (TARGETS["points"][0], "float[] widths", "flt[] widths")


def _stage(tmp_path, name: str, variant: str) -> str:
    """The stage file of TARGETS[name]: 'bad' (its type name damaged) or 'hidden' (intact and
    invisible); each in a folder of its own (USD keeps a layer it opened by its path)."""
    target, line, damaged = TARGETS[name]
    assert line in target
    if variant == "bad":
        target = target.replace(line, damaged)
    else:
        target = target.replace("    {\n", '    {\n        token visibility = "invisible"\n', 1)
    folder = tmp_path / variant
    folder.mkdir(exist_ok=True)
    path = folder / f"{name}.usda"
    path.write_text(PRELUDE + target + "}\n")
    return str(path)


def test_array_value_reads_arrays_and_names_an_unknown_type():
    layer = Sdf.Layer.CreateAnonymous(".usda")
    layer.ImportFromString(PRELUDE + TARGETS["mesh_indices"][0].replace("int[] faceVertexIndices",
                                                                         "in[] faceVertexIndices") + "}\n")
    stage = Usd.Stage.Open(layer)
    prim = stage.GetPrimAtPath("/World/Target")
    t = Usd.TimeCode(1)
    np.testing.assert_array_equal(array_value(prim.GetAttribute("faceVertexCounts"), t, np.int64), [4])
    assert value_count(prim.GetAttribute("points"), t) == 4
    assert array_value(prim.GetAttribute("holeIndices"), t, np.int64).shape == (0,)   # unauthored
    assert value_count(prim.GetAttribute("holeIndices"), t) == 0
    for read in (lambda a: array_value(a, t, np.int64), lambda a: value_count(a, t)):
        with pytest.raises(UnreadableValue, match=r"/World/Target\.faceVertexIndices .* type 'in\[\]'"):
            read(prim.GetAttribute("faceVertexIndices"))


@pytest.mark.parametrize("name", sorted(TARGETS))
def test_an_array_of_an_unknown_type_is_invalid_geometry_and_skip_invalid_drops_its_prim(tmp_path, name):
    bad = _stage(tmp_path, name, "bad")
    kw = dict(frame=1.5, method="analytic", resolution=(48, 36), samples=4)
    attribute = TARGETS[name][1].split()[1]
    with pytest.raises(InvalidGeometryError, match=rf"on /World/Target.*\.{attribute} is authored with type"):
        wb.render(bad, **kw)
    log.reset()
    r = wb.render(bad, skip_invalid=True, **kw)
    assert sum("dropping /World/Target" in w for w in r.stats["warnings"]) == 1, r.stats["warnings"]
    ref = wb.render(_stage(tmp_path, name, "hidden"), **kw)
    assert ref.rgba[..., 3].min() > 0.99   # the back wall fills the view
    np.testing.assert_allclose(r.rgba, ref.rgba, atol=1e-6)


@pytest.mark.parametrize("method", ["accumulation", "stochastic", "velocity"])
def test_every_method_drops_it(tmp_path, method):
    bad = _stage(tmp_path, "mesh_points", "bad")
    kw = dict(frame=1.5, method=method, resolution=(48, 36), samples=4)
    with pytest.raises(InvalidGeometryError):
        wb.render(bad, **kw)
    r = wb.render(bad, skip_invalid=True, **kw)
    np.testing.assert_allclose(r.rgba, wb.render(_stage(tmp_path, "mesh_points", "hidden"), **kw).rgba, atol=1e-6)


def _render_each(tmp_path, stages: dict[str, str]) -> dict:
    """name -> the frame of each stage text (each in a folder of its own, warnings said anew)."""
    results = {}
    for name, text in stages.items():
        (tmp_path / name).mkdir()
        path = tmp_path / name / "stage.usda"
        path.write_text(text)
        log.reset()
        results[name] = wb.render(str(path), frame=1.5, method="analytic", resolution=(48, 36), samples=4)
    return results


def test_normals_of_an_unknown_type_are_left_out_with_a_warning(tmp_path):
    """Normals are optional: the mesh renders as if it had none (flat facets), and says so."""
    target = TARGETS["mesh_indices"][0]
    target = target.replace("    {\n", '    {\n        uniform token subdivisionScheme = "none"\n', 1)
    normals = "        normal3f[] normals = [(0, 0, 1), (0, 0, 1), (0, 0, 1), (0.3, 0, 1)]\n"
    with_normals = lambda line: PRELUDE + target.replace("    {\n", "    {\n" + line, 1) + "}\n"  # noqa: E731
    r = _render_each(tmp_path, {"bad": with_normals(normals.replace("normal3f[]", "nrm3f[]")),
                                "none": PRELUDE + target + "}\n", "good": with_normals(normals)})
    assert any("/World/Target.normals is authored with a type USD does not know" in w
               for w in r["bad"].stats["warnings"]), r["bad"].stats["warnings"]
    np.testing.assert_array_equal(r["bad"].rgba, r["none"].rgba)
    assert np.abs(r["good"].rgba - r["none"].rgba).max() > 1e-3   # (the normals would have shown)


def test_a_light_size_of_an_unknown_type_takes_usds_fallback_with_a_warning(tmp_path):
    """A sphere light's `flot inputs:radius` raised TypeError in the frame (float() of an
    unregistered value); now it is USD's fallback radius (0.5), as a non-finite one is."""
    stage = PRELUDE + TARGETS["mesh_indices"][0] + "}\n"
    r = _render_each(tmp_path, {"bad": stage.replace("float inputs:radius = 0.25", "flot inputs:radius = 0.25"),
                                "fallback": stage.replace("float inputs:radius = 0.25", "float inputs:radius = 0.5")})
    assert any("inputs:radius" in w and "fallback 0.5" in w for w in r["bad"].stats["warnings"])
    assert r["fallback"].rgba[..., :3].max() > 0.05   # lit
    np.testing.assert_array_equal(r["bad"].rgba, r["fallback"].rgba)


def test_a_colour_primvar_of_an_unknown_type_is_ignored_with_a_warning(tmp_path):
    """displayColor of an unknown type: the mesh is USD's grey, as with none, and a warning says so."""
    target = TARGETS["mesh_indices"][0]
    colour = "        colr3f[] primvars:displayColor = [(1, 0, 0)]\n"
    r = _render_each(tmp_path, {"bad": PRELUDE + target.replace("    {\n", "    {\n" + colour, 1) + "}\n",
                                "none": PRELUDE + target + "}\n"})
    assert any("primvar displayColor is authored with a type USD does not know" in w
               for w in r["bad"].stats["warnings"]), r["bad"].stats["warnings"]
    np.testing.assert_array_equal(r["bad"].rgba, r["none"].rgba)
