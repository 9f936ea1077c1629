"""Hostile input (issue 17): non-finite material and light inputs fall back to USD's values with
a warning, so no NaN reaches a pixel."""

from __future__ import annotations

import os

import numpy as np
import pytest

import warp_blur as wb
from warp_blur.core import log

from conftest import SCENES

PRELUDE = """#usda 1.0
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
"""

STAGE = PRELUDE + """    def DistantLight "Sun"
    {
        color3f inputs:color = LIGHT_COLOR
        float inputs:intensity = LIGHT_INTENSITY
        bool inputs:normalize = 1
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
    log.reset()   # (outside a Renderer warnings are said once per process and prim)
    result = wb.render(str(path), frame=1, method=method, resolution=(32, 24), samples=2)
    assert np.isfinite(result.rgba).all()
    assert result.rgba[12, 16, :3].max() > 0.01      # the quad is lit, not black
    assert any("not a finite" in w for w in result.stats["warnings"]), result.stats["warnings"]


@pytest.mark.parametrize("name", ["roughness", "diffuseColor", "useSpecularWorkflow"])
def test_material_values_pass_the_finite_test_exactly_when_numpy_passes_them(name):
    """_finite's plain-Python test (no NumPy for ordinary values) accepts a value only where the
    NumPy test accepts it, and _finite keeps exactly the values NumPy accepts."""
    from pxr import Gf

    from warp_blur.usd.materials import FALLBACKS, _finite, _plainly_finite
    values = [0.5, 1, True, 0, -2.5e30, 1e30, float("nan"), float("inf"), "0.5", "abc", None, (0.1, 0.2, 0.3),
              Gf.Vec3f(0.1, 0.2, 0.3), (float("nan"), 0.0, 0.0), (1.0, 2.0), [[1.0, 2.0, 3.0]], np.array([1.0, 2.0, 3.0]),
              np.array([0.5]), (1e31, 0.0, 0.0), Gf.Vec2f(1, 2)]

    def numpy_accepts(value) -> bool:
        try:
            arr = np.asarray(value, np.float64).reshape(np.shape(FALLBACKS[name]))
            return bool(np.isfinite(arr).all()) and np.abs(arr).max(initial=0.0) <= 1e30
        except (TypeError, ValueError):
            return False
    log.reset()
    accepted = 0
    for value in values:
        if _plainly_finite(value, FALLBACKS[name]):
            assert numpy_accepts(value), value
            accepted += 1
        assert (_finite(value, name, "/M") is value) == numpy_accepts(value), value
    assert accepted >= 3


# ------------------------------------------------------------------ boundaries (issue 17)
def _quad(scene_path, **kw):
    from scenes import emissive_quad_stage
    return emissive_quad_stage(scene_path(), translate_samples={0: (-1, 0, 0), 2: (1, 0, 0)}, **kw)


def _cli(*args):
    import contextlib
    import io

    from warp_blur.tools.cli import main
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        code = main(list(args))
    return code, [ln for ln in err.getvalue().splitlines() if ln.strip()]


def test_negative_values_are_accepted_in_the_form_the_errors_suggest(tmp_path, scene_path):
    out = str(tmp_path / "a.exr")
    code, _ = _cli("render", _quad(scene_path), "-o", out, "--frame", "1", "--resolution", "16x12",
                   "--shutter", "-0.25:0.25", "--samples", "1", "--quiet")
    assert code == 0 and os.path.exists(out)
    code, lines = _cli("render", _quad(scene_path), "-o", out, "--resolution", "-5x5")
    assert code == 2 and len(lines) == 1 and "positive" in lines[0]


@pytest.mark.parametrize("camera,shutter,needle", [
    ({"focal": 0.0}, None, "focalLength"), ({"focal": float("nan")}, None, "focalLength"),
    ({"haperture": -24.0}, None, "horizontalAperture"), ({"hoffset": 1e30}, None, "horizontalApertureOffset"),
    ({}, "-1e9:1e9", "wider than"), ({}, "-0.5:1e6", "wider than"),
])
def test_bad_cameras_and_shutters_exit_2_naming_them(tmp_path, scene_path, camera, shutter, needle):
    from scenes import emissive_quad_stage
    path = emissive_quad_stage(scene_path(), camera=camera)
    out = str(tmp_path / "a.exr")
    args = ["render", path, "-o", out, "--frame", "1", "--resolution", "16x12", "--method", "analytic"]
    if shutter:
        args += ["--shutter", shutter]
    code, lines = _cli(*args)
    errors = [ln for ln in lines if "error" in ln]
    assert code == 2 and len(errors) == 1 and needle in errors[0] and not os.path.exists(out)


def test_a_hundred_million_frames_are_refused_before_any_work(tmp_path, scene_path):
    import time
    t0 = time.perf_counter()
    code, lines = _cli("render", _quad(scene_path), "-o", str(tmp_path / "f.####.exr"), "--frames", "1:100000000")
    assert code == 2 and "100,000,000 frames" in lines[-1] and time.perf_counter() - t0 < 30


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
def test_a_read_only_output_folder_fails_before_rendering(tmp_path, scene_path):
    folder = tmp_path / "ro"
    folder.mkdir()
    folder.chmod(0o555)
    code, lines = _cli("render", _quad(scene_path), "-o", str(folder / "a.exr"), "--frame", "1")
    assert code == 2 and "cannot write" in lines[-1]


def test_temporaries_of_live_runs_survive_and_outputs_follow_the_umask(tmp_path, scene_path):
    import socket
    import subprocess

    from warp_blur.tools.batch import remove_stale_temporaries
    from warp_blur.output.files import TEMP_PREFIX
    host = socket.gethostname().replace("-", "_")
    dead = subprocess.Popen(["true"])
    dead.wait()
    live = tmp_path / f"{TEMP_PREFIX}{host}-{os.getpid()}-abc.exr"
    stale = tmp_path / f"{TEMP_PREFIX}{host}-{dead.pid}-abc.exr"
    foreign = tmp_path / ".tmp-someone-else.exr"
    for p in (live, stale, foreign):
        p.write_text("x")
    assert remove_stale_temporaries([str(tmp_path / "f.0001.exr")]) == 1
    assert live.exists() and foreign.exists() and not stale.exists()
    old = os.umask(0o022)
    try:
        out = tmp_path / "a.exr"
        code, _ = _cli("render", _quad(scene_path), "-o", str(out), "--frame", "1", "--resolution", "8x6",
                       "--samples", "1", "--quiet")
    finally:
        os.umask(old)
    assert code == 0 and (out.stat().st_mode & 0o777) == 0o644


def test_a_zero_vertical_aperture_exits_2_naming_it(tmp_path, scene_path):
    from scenes import emissive_quad_stage
    from pxr import Usd, UsdGeom
    path = emissive_quad_stage(scene_path())
    stage = Usd.Stage.Open(path)
    UsdGeom.Camera(stage.GetPrimAtPath("/World/Cam")).GetVerticalApertureAttr().Set(0.0)
    stage.GetRootLayer().Save()
    code, lines = _cli("render", path, "-o", str(tmp_path / "a.exr"), "--frame", "1", "--resolution", "16x12")
    assert code == 2 and len(lines) == 1 and "verticalAperture" in lines[0]


def test_a_light_with_a_non_finite_transform_is_ignored_with_a_warning(tmp_path):
    text = STAGE
    for key, value in dict(DIFFUSE="(0.5, 0.5, 0.5)", ROUGHNESS="0.5", LIGHT_COLOR="(1, 1, 1)",
                           LIGHT_INTENSITY="2").items():
        text = text.replace(key, value)
    text = text.replace('''    def DistantLight "Sun"
    {''', '''    def SphereLight "Lamp"
    {
        double3 xformOp:translate = (0, inf, 3)
        uniform token[] xformOpOrder = ["xformOp:translate"]
    }
    def DistantLight "Sun"
    {''')
    path = tmp_path / "stage.usda"
    path.write_text(text)
    for method in ("analytic", "stochastic"):
        log.reset()
        result = wb.render(str(path), frame=1, method=method, resolution=(32, 24), samples=2)
        assert np.isfinite(result.rgba).all() and result.rgba[12, 16, :3].max() > 0.01   # the sun still lights it
        assert any("/World/Lamp" in w and "not finite" in w for w in result.stats["warnings"]), method


def _nan_translate_stage(tmp_path) -> str:
    """A camera whose translation is NaN: USD's C++ core prints its own warning on fd 2."""
    text = open(os.path.join(os.path.dirname(__file__), "..", "usd_scenes", "crossing.usda")).read()
    assert "double3 xformOp:translate = (0, 0, 10)" in text
    path = tmp_path / "nan.usda"
    path.write_text(text.replace("double3 xformOp:translate = (0, 0, 10)", "double3 xformOp:translate = (0, nan, 10)", 1))
    return str(path)


def test_usds_own_diagnostics_stay_hidden_unless_verbose(tmp_path):
    import subprocess
    import sys
    scene = _nan_translate_stage(tmp_path)
    args = [sys.executable, "-m", "warp_blur", "render", scene, "-o", str(tmp_path / "a.exr"),
            "--resolution", "16x12", "--samples", "1"]
    quiet = subprocess.run(args, capture_output=True, text=True, timeout=300)
    lines = [ln for ln in quiet.stderr.splitlines() if ln.strip()]
    assert quiet.returncode == 2 and len(lines) == 1 and lines[0].startswith("warp-blur: error:"), quiet.stderr
    loud = subprocess.run(args + ["--verbose"], capture_output=True, text=True, timeout=300)
    assert loud.returncode == 2 and "OrthogonalizeBasis" in loud.stderr and "warp-blur: error:" in loud.stderr


def test_a_frame_too_large_for_memory_is_refused_before_any_work(tmp_path, scene_path):
    import time
    t0 = time.perf_counter()
    code, lines = _cli("render", _quad(scene_path), "-o", str(tmp_path / "a.exr"), "--frame", "1",
                       "--resolution", "16384x16384", "--method", "analytic", "--memory-limit", "4096")
    assert code == 2 and len(lines) == 1 and "memory limit" in lines[0] and time.perf_counter() - t0 < 30
    with pytest.raises(wb.SettingsError, match="memory limit"):
        wb.Renderer(_quad(scene_path), resolution=(4096, 4096),
                    settings=wb.RenderSettings(method="velocity", frame_memory_limit_mb=100))
    from warp_blur.core.memory import frame_bytes
    assert frame_bytes("analytic", 100, 100, 2) == 4 * frame_bytes("analytic", 100, 100, 1)


def test_the_memory_estimate_counts_the_entry_tables_of_a_frame(scene_path, monkeypatch):
    """frame_bytes' per-triangle share for analytic and stochastic, beyond accumulation's, holds
    the entry tables a frame of theirs allocates (edge and corner tables), read off a render."""
    import warp_blur.methods.analytic as analytic
    import warp_blur.methods.stochastic as stochastic
    from warp_blur.core.memory import frame_bytes
    for module, method in ((analytic, "analytic"), (stochastic, "stochastic")):
        seen = []
        original = module.prepare_motion

        def recording(ctx, original=original, seen=seen):
            plan, geo, *rest = original(ctx)
            seen.append(((geo.entry_edges.capacity + geo.entry_corners.capacity), len(plan.entry_tri)))
            return (plan, geo, *rest)
        monkeypatch.setattr(module, "prepare_motion", recording)
        wb.render(_quad(scene_path), frame=1, resolution=(32, 24), method=method, samples=4, aovs=())
        table_bytes, entries = seen[0]
        extra = (frame_bytes(method, 1, 1, 1, 1000) - frame_bytes(method, 1, 1, 1, 0)
                 - frame_bytes("accumulation", 1, 1, 1, 1000) + frame_bytes("accumulation", 1, 1, 1, 0)) / 1000
        assert entries > 0 and extra >= table_bytes / entries, method


CUBE_STAGE = PRELUDE + """    def Cube "Box"
    {
        SIZE
    }
}
"""


def test_a_gprim_dimension_of_an_unknown_type_falls_back_to_the_schemas_with_a_warning(tmp_path):
    """`xdouble size = 1` (a type USD does not know) reads as an unregistered value: the cube takes
    the schema's fallback size (2), as if nothing were authored, and a warning names the attribute
    (the fuzz soak found it as a traceback through the batch's frame error)."""
    images = {}
    for name, size in (("bad", "xdouble size = 1"), ("fallback", "")):
        path = tmp_path / f"{name}.usda"
        path.write_text(CUBE_STAGE.replace("SIZE", size))
        log.reset()
        result = wb.render(str(path), frame=1, method="accumulation", resolution=(32, 24), samples=1)
        images[name] = result.rgba
        if name == "bad":
            assert any("/World/Box.size" in w and "not a number" in w for w in result.stats["warnings"])
    assert images["fallback"][..., 3].mean() > 0.05   # the cube is there
    np.testing.assert_array_equal(images["bad"], images["fallback"])


@pytest.mark.parametrize("distance", [1e30, 1e200])
@pytest.mark.parametrize("method", ["analytic", "stochastic", "accumulation", "velocity"])
def test_a_camera_absurdly_far_away_renders_what_it_sees(tmp_path, scene_path, method, distance):
    """A camera translated 1e30 or 1e200 from a scene near the origin (a fuzz mutant of the
    shadows stage): the general 4×4 inverse called its transform singular, or silently wrong,
    and every frame failed. The scene lies beyond the far plane: an empty frame, written."""
    from scenes import emissive_quad_stage
    from pxr import Gf, Usd, UsdGeom
    path = emissive_quad_stage(scene_path())
    stage = Usd.Stage.Open(path)
    cam = UsdGeom.Xformable(stage.GetPrimAtPath("/World/Cam"))
    for op in cam.GetOrderedXformOps():
        if op.GetOpType() == UsdGeom.XformOp.TypeTranslate:
            op.Set(Gf.Vec3d(0.0, 5.5, -distance))
    cam.AddRotateXOp(opSuffix="tilt").Set(-30.0)   # a turned camera: LU then fails on the far translation
    stage.GetRootLayer().Save()
    out = str(tmp_path / "far.exr")
    code, lines = _cli("render", path, "-o", out, "--frame", "1", "--resolution", "16x12", "--method", method,
                       "--samples", "2", "--quiet")
    assert code == 0 and os.path.exists(out), lines
    from warp_blur.output.files import read_exr
    img = read_exr(out)["RGBA"]
    assert np.isfinite(img).all() and img[..., 3].max() == 0.0


def test_a_camera_with_a_zero_scale_exits_2_naming_it(tmp_path, scene_path):
    from scenes import emissive_quad_stage
    from pxr import Gf, Usd, UsdGeom
    path = emissive_quad_stage(scene_path())
    stage = Usd.Stage.Open(path)
    UsdGeom.Xformable(stage.GetPrimAtPath("/World/Cam")).AddScaleOp(opSuffix="flat").Set(Gf.Vec3f(0.0, 0.0, 0.0))
    stage.GetRootLayer().Save()
    out = str(tmp_path / "a.exr")
    code, lines = _cli("render", path, "-o", out, "--frame", "1", "--resolution", "16x12", "--method", "analytic")
    assert code == 2 and len(lines) == 1 and "/World/Cam" in lines[0] and "inverted" in lines[0]
    assert not os.path.exists(out)


def test_invert_affine_inverts_far_transforms_exactly():
    from warp_blur.core.affine import invert_affine
    c, s = np.cos(0.3), np.sin(0.3)
    for t in (5.0, 1e30, 1e200):
        m = np.array([[1, 0, 0, 0], [0, c, s, 0], [0, -s, c, 0], [2.0, 5.5, -t, 1]], np.float64)
        inv = invert_affine(m)
        np.testing.assert_allclose(inv[:3, :3], m[:3, :3].T, atol=1e-15)
        np.testing.assert_allclose(inv[3, :3], -m[3, :3] @ m[:3, :3].T, rtol=1e-12)
    with pytest.raises(np.linalg.LinAlgError):
        invert_affine(np.diag([0.0, 1.0, 1.0, 1.0]))


def test_zero_scales_on_a_mesh_with_normals_and_on_a_textured_dome_render(tmp_path, scene_path):
    """Valid USD that inverted a singular matrix and failed the frame: a mesh with authored
    normals scaled to zero (collapsed, so nothing of it shows) and a textured dome light scaled to
    zero (no orientation: its map is read unrotated, with a warning)."""
    from PIL import Image
    from pxr import Gf, Usd, UsdGeom, UsdLux, Vt
    from scenes import emissive_quad_stage
    path = emissive_quad_stage(scene_path(), with_light=True)
    stage = Usd.Stage.Open(path)
    mesh = next(UsdGeom.Mesh(p) for p in stage.Traverse() if p.IsA(UsdGeom.Mesh))
    count = len(mesh.GetPointsAttr().Get())
    mesh.CreateNormalsAttr(Vt.Vec3fArray([Gf.Vec3f(0, 0, 1)] * count))
    mesh.SetNormalsInterpolation("vertex")
    UsdGeom.Xformable(mesh).AddScaleOp(opSuffix="flat").Set(Gf.Vec3f(0.0, 0.0, 0.0))
    Image.fromarray(np.full((8, 16, 3), 128, np.uint8)).save(str(tmp_path / "sky.png"))
    dome = UsdLux.DomeLight.Define(stage, "/World/Sky")
    dome.CreateTextureFileAttr(str(tmp_path / "sky.png"))
    UsdGeom.Xformable(dome).AddScaleOp().Set(Gf.Vec3f(0.0, 0.0, 0.0))
    stage.GetRootLayer().Save()
    for method in ("analytic", "velocity"):
        out = str(tmp_path / f"{method}.exr")
        code, lines = _cli("render", path, "-o", out, "--frame", "1", "--resolution", "16x12", "--method", method)
        assert code == 0 and os.path.exists(out), lines
        from warp_blur.output.files import read_exr
        img = read_exr(out)["RGBA"]
        assert np.isfinite(img).all() and img[..., 3].max() == 0.0 and img[..., :3].min() > 0.0   # the sky only



def test_zero_scaled_points_render(tmp_path, scene_path):
    """UsdGeomPoints scaled to zero (valid USD): their discs face the camera through the prim's
    inverse transform, which is singular; they collapse and the frame renders."""
    from pxr import Gf, Usd, UsdGeom, Vt
    from scenes import emissive_quad_stage
    path = emissive_quad_stage(scene_path(), with_light=True)
    stage = Usd.Stage.Open(path)
    dust = UsdGeom.Points.Define(stage, "/World/Dust")
    dust.CreatePointsAttr(Vt.Vec3fArray([Gf.Vec3f(0, 0, 0), Gf.Vec3f(0.5, 0.2, 0)]))
    dust.CreateWidthsAttr(Vt.FloatArray([0.3, 0.3]))
    UsdGeom.Xformable(dust).AddScaleOp().Set(Gf.Vec3f(0.0, 0.0, 0.0))
    stage.GetRootLayer().Save()
    out = str(tmp_path / "dust.exr")
    code, lines = _cli("render", path, "-o", out, "--frame", "1", "--resolution", "16x12", "--method", "analytic")
    assert code == 0 and os.path.exists(out), lines


@pytest.mark.parametrize("method", ["analytic", "stochastic"])
def test_a_frame_whose_motion_entries_would_not_fit_is_refused_once_they_are_planned(scene_path, method):
    """Eight quads each turning a full circle over the shutter: 16 triangles, 512 entries (one per
    motion segment). A memory limit above the frame counted one entry a triangle but below its
    planned entries is a one-line SettingsError naming them; just above them, it renders."""
    import sys
    sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "stages"))
    from authoring import add_camera, add_quad, new_stage

    from warp_blur.core.memory import ENTRY_TABLE_BYTES, frame_bytes
    path = scene_path()
    stage = new_stage(path)
    add_camera(stage)
    for i in range(8):
        add_quad(stage, f"/World/Q{i}", 1.0, 0.2, translate=(i * 0.5 - 2, 0, -i), rotate_axis="Z",
                 rotate_samples={0: 0, 2: 720})
    stage.GetRootLayer().Save()
    first = wb.render(path, frame=1, resolution=(32, 24), method=method, samples=4, aovs=())
    triangles, entries = first.stats["triangles"], first.stats["entries"]
    assert entries >= 16 * triangles
    one_each = frame_bytes(method, 32, 24, 1, triangles)
    planned = one_each + ENTRY_TABLE_BYTES[method] * (entries - triangles)
    with pytest.raises(wb.SettingsError, match=f"{triangles} triangles in {entries} motion entries"):
        wb.render(path, frame=1, resolution=(32, 24), method=method, samples=4, aovs=(),
                  frame_memory_limit_mb=(one_each + planned) / 2 / 2**20)
    again = wb.render(path, frame=1, resolution=(32, 24), method=method, samples=4, aovs=(),
                      frame_memory_limit_mb=planned * 1.01 / 2**20)
    assert again.stats["entries"] == entries


def _rotation_variant(tmp_path, old: str, new: str, scene: str = "rotation") -> str:
    """usd_scenes/rotation.usda (or `scene`) with one line's text replaced (a hand-made hostile stage)."""
    text = open(os.path.join(os.path.dirname(__file__), "..", "usd_scenes", f"{scene}.usda")).read()
    assert old in text
    path = str(tmp_path / "variant.usda")
    with open(path, "w") as f:
        f.write(text.replace(old, new, 1))
    return path


def test_a_time_sample_at_a_non_finite_time_exits_2_naming_usds_failure(tmp_path):
    """USD fails its own verification when asked whether a value with a `nan:` time sample may
    vary (found by the fuzzer, seed 5704): one line naming the stage and USD's failure, exit 2,
    no output (before: a Tf.ErrorException reported as a failed frame, exit 1)."""
    path = _rotation_variant(tmp_path, "1.5: 0,", "nan: 0,")
    out = str(tmp_path / "out.exr")
    code, err = _cli("render", path, "-o", out, "--method", "velocity", "--resolution", "32x24")
    lines = [ln for ln in err if "WARNING" not in ln]
    assert code == 2 and len(lines) == 1 and "USD cannot evaluate" in lines[0] and "frame 1" in lines[0]
    assert not os.path.exists(out)


@pytest.mark.filterwarnings("ignore::RuntimeWarning")   # NumPy's overflow notes on 1e300 (the CLI hides them)
@pytest.mark.parametrize("method", ["stochastic", "velocity"])
def test_a_cube_of_size_minus_1e300_under_a_light_renders(tmp_path, method):
    """A cube of size -1e300 (found by the fuzzer, seed 5704): the shadow casters' size bound
    overflowed Python's float power (OverflowError, a failed frame); now no plane qualifies."""
    path = _rotation_variant(tmp_path, "double size = 1.4", "double size = -1e300")
    r = wb.render(path, frame=1, method=method, resolution=(32, 24), samples=2, shadow_map_size=64)
    assert np.isfinite(r.rgba).all()


NAN_BOX = {
    "always": "double3 xformOp:translate = (nan, -0.3, 0)",
    "from a time sample on": "double3 xformOp:translate.timeSamples = { 1.5: (2.2, -0.3, 0), 2.5: (nan, -0.3, 0) }",
    # NaN only between 1.6 and 1.8, inside frame 2's shutter (1.5-2.5) and away from its open,
    # centre and close: found by a later snapshot, after others showed the box
    "within the shutter only": "double3 xformOp:translate.timeSamples = { 1.5: (2.2, -0.3, 0), 1.6: (2.2, -0.3, 0), "
                               "1.7: (nan, -0.3, 0), 1.8: (2.2, -0.3, 0) }",
}


# the velocity method reads the stage at open, centre and close only (test below)
NAN_BOX_CASES = [(m, w) for w in sorted(NAN_BOX) for m in ("analytic", "stochastic", "accumulation", "velocity")
                 if (m, w) != ("velocity", "within the shutter only")]


@pytest.mark.parametrize("method,where", NAN_BOX_CASES)
def test_skip_invalid_drops_a_prim_whose_transform_is_not_finite(tmp_path, method, where):
    """The error for a prim whose transformed points are not finite says --skip-invalid drops it,
    and it now does (before, the check ran at each snapshot and raised whatever the flag): one
    warning naming the prim, and the frame is the frame without it, at every time: equal to the
    stage with the box made invisible. A box first found non-finite after other snapshots showed
    it makes the Renderer render the frame again with it hidden throughout."""
    path = _rotation_variant(tmp_path, "double3 xformOp:translate = (2.2, -0.3, 0)", NAN_BOX[where])
    out = str(tmp_path / "out.exr")
    code, err = _cli("render", path, "-o", out, "--method", method, "--resolution", "32x24", "--frames", "2")
    assert code == 2 and not os.path.exists(out)
    assert "invalid geometry on /World/Box: non-finite transformed points" in err[-1] and "--skip-invalid" in err[-1]
    log.reset()
    code, err = _cli("render", path, "-o", out, "--method", method, "--resolution", "32x24", "--frames", "2",
                     "--skip-invalid")
    warned = [ln for ln in err if "WARNING" in ln and "dropping /World/Box" in ln]
    assert code == 0 and os.path.exists(out) and len(warned) == 1, err
    kw = dict(frame=2.0, method=method, resolution=(32, 24), samples=4, aovs=("Z", "motion"))
    r = wb.render(path, skip_invalid=True, **kw)
    (tmp_path / "hidden").mkdir()   # (another file: USD keeps the layer it opened at a path)
    hidden = _rotation_variant(tmp_path / "hidden",
                               'uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateX"]',
                               'uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateX"]\n'
                               '        token visibility = "invisible"')
    ref = wb.render(hidden, **kw)
    assert np.isfinite(r.rgba).all() and r.rgba[..., 3].max() > 0   # the propeller is there
    np.testing.assert_allclose(r.rgba, ref.rgba, atol=1e-6)
    for name in ("Z", "motion"):
        np.testing.assert_allclose(r.aovs[name], ref.aovs[name], atol=1e-5)


def test_velocity_reads_the_stage_at_open_centre_and_close_only(tmp_path):
    """The velocity method reads the stage at the shutter's open, centre and close alone: a box
    whose transform is NaN only between them (1.6-1.8 in frame 2's 1.5-2.5) is where those three
    put it, and the frame renders as the stage's own (exit 0, no warning). Until session 67 its
    shadow maps' probes read the stage at other times too and found the NaN; the sun there shadows
    nothing lit, so it gets no maps now (shadows/pairs.py)."""
    path = _rotation_variant(tmp_path, "double3 xformOp:translate = (2.2, -0.3, 0)",
                             NAN_BOX["within the shutter only"])
    out = str(tmp_path / "out.exr")
    code, err = _cli("render", path, "-o", out, "--method", "velocity", "--resolution", "32x24", "--frames", "2")
    assert code == 0 and os.path.exists(out) and not [ln for ln in err if "WARNING" in ln and "Box" in ln], err
    kw = dict(frame=2.0, method="velocity", resolution=(32, 24), aovs=())
    r = wb.render(path, **kw)
    assert r.stats["shadow_lights_unneeded"] == 1
    np.testing.assert_array_equal(r.rgba, wb.render(os.path.join(SCENES, "rotation.usda"), **kw).rgba)


@pytest.mark.parametrize("method", ["analytic", "stochastic", "accumulation", "velocity"])
@pytest.mark.filterwarnings("ignore::RuntimeWarning")   # NumPy's overflow notes on 1e300 (the CLI hides them)
def test_a_prim_at_1e300_under_a_shadowing_light_renders(tmp_path, method):
    """A box translated to y = 1e300 under a sun and a rect lamp with shadows (found by the fuzzer, seed 5707, on
    the shadows stage; it fails the same way at the session's start): a light left with no faces
    broke a reshape (every method), and with that mended, the maps fitted around the box had inf
    windows and near planes in float32 and every lookup was NaN (a frame of non-finite pixels,
    nothing written). Points beyond shadows.maps.FIT_LIMIT are left out of the fit: the rest of
    the stage renders with its shadows, the far box casts none."""
    path = _rotation_variant(tmp_path, "double3 xformOp:translate = (1.5, 1.6, -2)",
                             "double3 xformOp:translate = (1.5, 1e300, -2)", scene="shadows")
    r = wb.render(path, frame=1, method=method, resolution=(32, 24), samples=4, shadow_map_size=64)
    assert np.isfinite(r.rgba).all() and r.rgba[..., 3].max() > 0
    assert r.stats["shadow_lights"] == 2


def test_a_light_with_no_faces_takes_no_face_slot():
    """slot_faces reshaped a light's face rows with -1 for their width, which has no size when the
    light has no faces (no geometry in any of its cube's faces): an explicit width now."""
    from types import SimpleNamespace

    from warp_blur.kernels.shadow_lookup import FACE_WIDTH
    from warp_blur.raster.device_data import slot_faces
    rows = np.arange(2 * 3 * FACE_WIDTH, dtype=np.float32).reshape(6, FACE_WIDTH)   # light 1: 1 sample, 3 faces, 2 instants
    data = SimpleNamespace(times=2, size=8, faces=rows, lights=np.array([[0, 1, 0], [0, 1, 3]]))
    faces, lights = slot_faces(data)
    assert faces.shape == (3, FACE_WIDTH) and lights[0, 0] == 0 and lights[1, 0] == 0
    np.testing.assert_array_equal(faces, rows[:3])


@pytest.mark.parametrize("fps", ["inf", "1e300", "1e-300", "25"])   # (USD refuses nan, 0 and -24 as it reads)
def test_a_frame_rate_that_is_not_a_finite_positive_number_is_left_out_of_the_exr(tmp_path, fps):
    """`framesPerSecond = inf` (found by the fuzzer, seed 5709; fails the same way at 2cbb900):
    the EXR's framesPerSecond attribute, a rational, raised OverflowError after the frame had
    rendered (a failed frame). `1e300` (seed 5716, on the Teapot's geometry layer) overflowed the
    rational's int32 numerator the same way (SystemError); `1e-300` rounds to 0. Such a rate is
    now left out of the file; 25 is written."""
    path = _rotation_variant(tmp_path, "framesPerSecond = 24", f"framesPerSecond = {fps}")
    out = str(tmp_path / "out.exr")
    code, err = _cli("render", path, "-o", out, "--method", "velocity", "--resolution", "32x24", "--frames", "2")
    assert code == 0 and os.path.exists(out), err
    import OpenEXR
    header = OpenEXR.InputFile(out).header()
    assert ("framesPerSecond" in header) == (fps == "25")
