"""Cutout opacity (opacity with opacityThreshold > 0): a closed form for a moving masked quad in
every method, and a cutout against the geometry it leaves, lit and shadowed, still and moving."""

import os

import numpy as np
import pytest
from authoring import (add_camera, add_distant_light, add_material, add_mesh, add_quad, add_textured_material,
                       new_stage, set_st)
from PIL import Image
from pxr import Gf, Sdf, UsdShade

import warp_blur as wb
from warp_blur.output.metrics import rmse

W, H = 96, 64
METHODS = [("analytic", {"time_bits": 0, "samples": 4}, 0.01),
           ("accumulation", {"samples": 128}, 0.01),
           ("stochastic", {"samples": 256}, 0.03)]


def _step_image(folder: str) -> str:
    """A 512-wide step (0 left of s = 0.5, 255 right), saved as folder/step.png."""
    step = np.zeros((4, 512, 3), np.uint8)
    step[:, 256:] = 255
    Image.fromarray(step).save(os.path.join(folder, "step.png"))
    return "./step.png"


def _cutout_material(stage, path: str, image: str, emissive=(1.0, 1.0, 1.0), diffuse=(0.0, 0.0, 0.0),
                     threshold: float = 0.5) -> UsdShade.Material:
    """Emissive (and diffuse) constant, opacity from the texture's r, masked at `threshold`."""
    mat = add_textured_material(stage, path, image, input_name="opacity", output="r")
    surface = UsdShade.Shader.Get(stage, f"{path}/PreviewSurface")
    surface.GetInput("emissiveColor").Set(Gf.Vec3f(*emissive))
    surface.GetInput("diffuseColor").Set(Gf.Vec3f(*diffuse))
    surface.CreateInput("opacityThreshold", Sdf.ValueTypeNames.Float).Set(threshold)
    return mat


def _masked_quad_stage(path: str, translate_samples=None) -> str:
    """A 4×2 quad (s across x) whose left half (s < 0.5) is cut out, emissive white, no dome."""
    stage = new_stage(path)
    add_camera(stage, translate=(0, 0, 8), focal=24.0, haperture=36.0, vaperture=24.0)
    mat = _cutout_material(stage, "/World/Looks/Cut", _step_image(os.path.dirname(path)))
    quad = add_quad(stage, "/World/Quad", 2.0, 1.0, material=mat, translate=None if translate_samples else (0, 0, 0),
                    translate_samples=translate_samples)
    set_st(quad, [(0, 0), (1, 0), (1, 1), (0, 1)])
    stage.GetRootLayer().Save()
    return path


def _world_x(scene_path) -> tuple[np.ndarray, np.ndarray]:
    """World x (on the quad plane) of each column of the middle row, and where the still quad
    covers it: from a render of an s-ramp quad (s = (x + 2) / 4)."""
    path = scene_path()
    ramp = np.repeat(np.arange(256, dtype=np.uint8)[None, :, None], 4, axis=0).repeat(3, axis=2)
    Image.fromarray(ramp).save(os.path.join(os.path.dirname(path), "ramp.png"))
    stage = new_stage(path)
    add_camera(stage, translate=(0, 0, 8), focal=24.0, haperture=36.0, vaperture=24.0)
    mat = add_textured_material(stage, "/World/Looks/Ramp", "./ramp.png")
    set_st(add_quad(stage, "/World/Quad", 2.0, 1.0, material=mat, translate=(0, 0, 0)),
           [(0, 0), (1, 0), (1, 1), (0, 1)])
    stage.GetRootLayer().Save()
    r = wb.render(path, frame=1, samples=1, resolution=(W, H), shutter=(0.0, 0.0))
    return 4.0 * r.rgba[H // 2, :, 0] - 2.0, r.rgba[H // 2, :, 3] > 0.999


def test_the_cut_out_half_of_a_still_quad_is_not_there(scene_path):
    x, inside = _world_x(scene_path)
    path = _masked_quad_stage(scene_path())
    cols = np.nonzero(inside)[0]
    left, right = cols[x[cols] < -0.1], cols[x[cols] > 0.1]
    assert len(left) > 10 and len(right) > 10
    for method in ("accumulation", "stochastic", "analytic", "velocity"):
        r = wb.render(path, frame=1, method=method, samples=4, resolution=(W, H), shutter=(0.0, 0.0))
        alpha = r.rgba[H // 2, :, 3]
        assert alpha[left].max() == 0.0, method
        assert alpha[right].min() == pytest.approx(1.0), method


@pytest.mark.parametrize("method,kw,tol", METHODS)
def test_a_moving_cutout_covers_each_pixel_for_its_closed_form_time(scene_path, method, kw, tol):
    """The quad's centre moves from x = -1 to 1 over the shutter and only its right half [c, c + 2]
    is there: a pixel at world x is covered for clip(min((x + 1) / 2, (3 - x) / 2), 0, 1) of it."""
    x, inside = _world_x(scene_path)
    path = _masked_quad_stage(scene_path(), translate_samples={0.5: (-1, 0, 0), 1.5: (1, 0, 0)})
    r = wb.render(path, frame=1, method=method, resolution=(W, H), **kw)
    expected = np.clip(np.minimum((x + 1.0) / 2.0, (3.0 - x) / 2.0), 0.0, 1.0)
    cols = np.nonzero(inside)[0]
    cols = cols[(x[cols] > -1.9) & (x[cols] < 1.9)]
    got = r.rgba[H // 2, cols, 3]
    assert np.abs(got - expected[cols]).max() < tol
    assert ((expected[cols] > 0.1) & (expected[cols] < 0.9)).sum() >= 8, "the blur spans many pixels"


def _occluder_stage(path: str, cutout: bool, moving: bool) -> str:
    """A lit ground under an overhead distant light, a dark square occluder above it: with
    `cutout`, its left half is cut out by its material; without, only its right half is modelled."""
    stage = new_stage(path)
    add_camera(stage, translate=(0.0, 4.0, 4.0), rotate_axis="X", rotate_samples={0: -45.0})
    grey = add_material(stage, "/World/Looks/Grey", diffuse=(0.8, 0.8, 0.8), roughness=1.0)
    add_mesh(stage, "/World/Ground", [(-2.5, 0, 2.5), (2.5, 0, 2.5), (2.5, 0, -2.5), (-2.5, 0, -2.5)], [4],
             [0, 1, 2, 3], material=grey)
    add_distant_light(stage, "/World/Light", intensity=3.0, rotate=(-90, 0, 0))
    place = ({"translate_samples": {0.5: (-0.9, 1.0, 0.0), 1.5: (0.3, 1.0, 0.0)}} if moving
             else {"translate": (-0.3, 1.0, 0.0)})
    if cutout:
        mat = _cutout_material(stage, "/World/Looks/Cut", _step_image(os.path.dirname(path)),
                               emissive=(0.05, 0.05, 0.05), diffuse=(0.3, 0.1, 0.1))
        square = [(-0.4, 0, 0.4), (0.4, 0, 0.4), (0.4, 0, -0.4), (-0.4, 0, -0.4)]
        mesh = add_mesh(stage, "/World/Occluder", square, [4], [0, 1, 2, 3], material=mat, **place)
        set_st(mesh, [(0, 0), (1, 0), (1, 1), (0, 1)])
    else:
        mat = add_material(stage, "/World/Looks/Dark", emissive=(0.05, 0.05, 0.05), diffuse=(0.3, 0.1, 0.1))
        half = [(0.0, 0, 0.4), (0.4, 0, 0.4), (0.4, 0, -0.4), (0.0, 0, -0.4)]
        add_mesh(stage, "/World/Occluder", half, [4], [0, 1, 2, 3], material=mat, **place)
    stage.GetRootLayer().Save()
    return path


@pytest.mark.parametrize("moving", [False, True], ids=["still", "moving"])
def test_a_cutout_renders_and_shadows_like_the_geometry_it_leaves(scene_path, moving):
    """Every method: the masked square, lit, casting its shadow (shadow maps test the mask too),
    against a square of only its opaque half; they differ only along the mask's edge."""
    cut = _occluder_stage(scene_path(), cutout=True, moving=moving)
    half = _occluder_stage(scene_path(), cutout=False, moving=moving)
    for method in ("accumulation", "stochastic", "analytic", "velocity"):
        kw = dict(frame=1, method=method, samples=16, resolution=(W, H), shadows="direct")
        a = wb.render(cut, **kw).rgba
        b = wb.render(half, **kw).rgba
        diff = np.abs(a - b).max(axis=2)
        assert rmse(a, b) < 0.01, method
        assert (diff > 0.05).mean() < 0.01, method


def _translucent_stage(path: str, layers, shutter=(-0.5, 0.5), moving: bool = False) -> str:
    """Emissive quads facing the camera, nearest first: (colour, opacity) each, over the dome
    (black); with `moving` the nearest slides across the others over the shutter."""
    stage = new_stage(path)
    add_camera(stage, translate=(0, 0, 8), shutter=shutter)
    for i, (color, opacity) in enumerate(layers):
        mat = add_material(stage, f"/World/Looks/L{i}", emissive=color)
        UsdShade.Shader.Get(stage, f"/World/Looks/L{i}/PreviewSurface").GetInput("opacity").Set(float(opacity))
        place = ({"translate_samples": {0.5: (-1.0, 0, 0), 1.5: (1.0, 0, 0)}} if moving and i == 0
                 else {"translate": (0, 0, -0.5 * i)})
        add_quad(stage, f"/World/Q{i}", 1.5 - 0.1 * i if moving else 2.0, 1.5, material=mat, **place)
    stage.GetRootLayer().Save()
    return path


WHITE, GREEN, RED = (1.0, 1.0, 1.0), (0.0, 1.0, 0.0), (1.0, 0.0, 0.0)


@pytest.mark.parametrize("method,samples,tol", [("accumulation", 64, 0.02), ("stochastic", 64, 0.03),
                                                ("analytic", 16, 0.02), ("velocity", 8, 0.02)])
def test_fractional_opacity_composites_layers_over_each_other(scene_path, method, samples, tol):
    """A still stack, sharp shutter: 50% white over 50% green over opaque red is
    0.5 W + 0.25 G + 0.25 R; 40% white alone over the dome is 0.4 W with alpha 0.4 (premultiplied).
    Means over a patch of pixels (each pixel samples presence at its own offsets; the velocity
    method averages 8 presence passes of its one instant)."""
    stack = _translucent_stage(scene_path(), [(WHITE, 0.5), (GREEN, 0.5), (RED, 1.0)], shutter=(0.0, 0.0))
    alone = _translucent_stage(scene_path(), [(WHITE, 0.4)], shutter=(0.0, 0.0))
    patch = (slice(19, 45), slice(28, 68))   # inside the farthest quad (rows 18..46, columns 27..69)
    kw = dict(frame=1, method=method, samples=samples, resolution=(W, H))
    a = wb.render(stack, **kw).rgba[patch].reshape(-1, 4).mean(axis=0)
    np.testing.assert_allclose(a, (0.75, 0.75, 0.5, 1.0), atol=tol)
    b = wb.render(alone, **kw).rgba[patch].reshape(-1, 4).mean(axis=0)
    np.testing.assert_allclose(b, (0.4, 0.4, 0.4, 0.4), atol=tol)


def test_a_moving_translucent_quad_blurs_alike_in_every_method(scene_path):
    path = _translucent_stage(scene_path(), [(WHITE, 0.6), (RED, 1.0)], moving=True)
    kw = dict(frame=1, resolution=(W, H))
    ref = wb.render(path, method="accumulation", samples=128, **kw).rgba
    for method, tol in (("analytic", 0.03), ("stochastic", 0.05)):
        got = wb.render(path, method=method, samples=64 if method == "stochastic" else 16, **kw).rgba
        assert rmse(got, ref) < tol, method
    opaque = wb.render(_translucent_stage(scene_path(), [(WHITE, 1.0), (RED, 1.0)], moving=True),
                       method="accumulation", samples=128, **kw).rgba
    assert rmse(opaque, ref) > 0.05, "the translucency shows"


def _display_opacity_stage(path: str, interpolation: str, values, threshold: float = 0.0) -> str:
    """A 4×2 emissive white quad (x from -2 to 2, two faces split at x = 0) whose material's
    opacity reads the primvar displayOpacity (a UsdPrimvarReader_float), authored `values` with
    `interpolation`, over the black dome."""
    stage = new_stage(path)
    add_camera(stage, translate=(0, 0, 8), focal=24.0, haperture=36.0, vaperture=24.0, shutter=(0.0, 0.0))
    mat = add_material(stage, "/World/Looks/M", emissive=WHITE)
    surface = UsdShade.Shader.Get(stage, "/World/Looks/M/PreviewSurface")
    reader = UsdShade.Shader.Define(stage, "/World/Looks/M/Opacity")
    reader.CreateIdAttr("UsdPrimvarReader_float")
    reader.CreateInput("varname", Sdf.ValueTypeNames.String).Set("displayOpacity")
    reader.CreateInput("fallback", Sdf.ValueTypeNames.Float).Set(1.0)
    surface.GetInput("opacity").ConnectToSource(reader.ConnectableAPI(), "result")
    if threshold:
        surface.CreateInput("opacityThreshold", Sdf.ValueTypeNames.Float).Set(threshold)
    mesh = add_mesh(stage, "/World/Quad", [(-2, -1, 0), (0, -1, 0), (2, -1, 0), (-2, 1, 0), (0, 1, 0), (2, 1, 0)],
                    [4, 4], [0, 1, 4, 3, 1, 2, 5, 4], material=mat)
    mesh.CreateDisplayOpacityPrimvar(interpolation).Set(list(values))
    stage.GetRootLayer().Save()
    return path


def _column_alpha(rgba: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(world x of each column inside the quad, mean alpha down those columns over the quad's
    rows): the camera sees 12 units across 96 columns, the quad spans columns 32..63."""
    cols = np.arange(33, 63)
    return (cols + 0.5) / 8.0 - 6.0, rgba[26:38, cols, 3].mean(axis=0)


@pytest.mark.parametrize("method,samples,tol", [("accumulation", 64, 0.04), ("stochastic", 64, 0.05),
                                                ("analytic", 16, 0.04), ("velocity", 8, 0.04)])
def test_display_opacity_in_every_interpolation(scene_path, method, samples, tol):
    """displayOpacity read through the material's primvar reader: vertex values 0 at x = -2 and 1
    at x = 2 give coverage (x + 2) / 4 across the quad; uniform (0.25, 0.75) one per face;
    faceVarying as vertex; constant 0.4 everywhere; with opacityThreshold 0.5 the vertex ramp
    masks to x > 0 (opaque). Means of alpha over bands of columns of 72 pixels (fractional
    presence is sampled per pixel: per time sample, per slot, or over the velocity method's 8
    stratified presence passes)."""
    kw = dict(frame=1, method=method, samples=samples, resolution=(W, H))
    ramp = [0.0, 0.5, 1.0, 0.0, 0.5, 1.0]
    cases = [("vertex", ramp, 0.0, lambda x: (x + 2) / 4),
             ("faceVarying", [0.0, 0.5, 0.5, 0.0, 0.5, 1.0, 1.0, 0.5], 0.0, lambda x: (x + 2) / 4),
             ("uniform", [0.25, 0.75], 0.0, lambda x: np.where(x < 0, 0.25, 0.75)),
             ("constant", [0.4], 0.0, lambda x: np.full_like(x, 0.4)),
             ("vertex", ramp, 0.5, lambda x: (x > 0).astype(float))]
    for interpolation, values, threshold, want in cases:
        x, alpha = _column_alpha(wb.render(_display_opacity_stage(scene_path(), interpolation, values, threshold),
                                           **kw).rgba)
        err = (alpha - want(x)).reshape(5, 6).mean(axis=1)        # bands of 6 columns (12 rows each)
        assert np.abs(err).max() < tol, (interpolation, threshold, err)


def test_display_opacity_on_the_display_color_material(scene_path):
    """A prim with no material renders displayColor with displayOpacity (USD's fallback surface):
    constant 0.3 covers 30% of the quad, a quad without it is opaque."""
    path = scene_path()
    stage = new_stage(path)
    add_camera(stage, translate=(0, 0, 8), focal=24.0, haperture=36.0, vaperture=24.0, shutter=(0.0, 0.0))
    add_quad(stage, "/World/Quad", 2.0, 1.0).CreateDisplayOpacityPrimvar("constant").Set([0.3])
    add_quad(stage, "/World/Far", 0.5, 0.5, translate=(4.0, 0, 0))
    stage.GetRootLayer().Save()
    rgba = wb.render(path, frame=1, method="accumulation", samples=64, resolution=(W, H)).rgba
    assert abs(rgba[26:38, 33:63, 3].mean() - 0.3) < 0.03
    np.testing.assert_allclose(rgba[30:34, 81:83, 3], 1.0)
