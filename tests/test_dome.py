"""Textured DomeLight: the latlong orientation against UsdLux's (OpenEXR's) definition with USD's
own camera transform, SH irradiance against a brute-force integral, every method alike."""

import os

import numpy as np
import pytest
from authoring import add_material, add_quad, new_stage
from PIL import Image
from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux

import warp_blur as wb
from warp_blur.output.metrics import rmse
from warp_blur.usd.dome import irradiance_sh, latlong_directions, sh_basis
from warp_blur.usd.textures import srgb_to_linear


def _uv_map(folder: str, w: int = 512, h: int = 256) -> str:
    """A latlong map whose red is its s coordinate and green its t (t = 0 at the bottom row)."""
    s = (np.arange(w) + 0.5) / w
    t = 1.0 - (np.arange(h) + 0.5) / h
    img = np.zeros((h, w, 3), np.uint8)
    img[..., 0] = np.round(s[None, :] * 255)
    img[..., 1] = np.round(t[:, None] * 255)
    Image.fromarray(img).save(os.path.join(folder, "uv_dome.png"))
    return "./uv_dome.png"


def _dome_stage(path: str, yaw: float, pitch: float, with_quad: bool = False) -> str:
    stage = new_stage(path)
    cam = UsdGeom.Camera.Define(stage, "/World/Cam")
    cam.CreateFocalLengthAttr(50.0)
    cam.CreateHorizontalApertureAttr(24.0)
    cam.CreateVerticalApertureAttr(24.0)
    cam.CreateShutterOpenAttr(-0.5)
    cam.CreateShutterCloseAttr(0.5)
    cam.AddRotateYOp().Set(yaw)
    cam.AddRotateXOp().Set(pitch)
    dome = UsdLux.DomeLight.Define(stage, "/World/Dome")
    dome.CreateTextureFileAttr(Sdf.AssetPath(_uv_map(os.path.dirname(path))))
    dome.CreateTextureFormatAttr("latlong")
    mat = add_material(stage, "/World/Looks/White", diffuse=(0.8, 0.8, 0.8))
    view = UsdGeom.Xformable(cam).ComputeLocalToWorldTransform(Usd.TimeCode(1)).TransformDir(Gf.Vec3d(0, 0, -1))
    if with_quad:   # moving across the view, 4 units ahead
        add_quad(stage, "/World/Quad", 0.15, 0.15, material=mat,
                 translate_samples={0.5: tuple(view * 4.0 - Gf.Vec3d(0.1, 0, 0)),
                                    1.5: tuple(view * 4.0 + Gf.Vec3d(0.1, 0, 0))})
    else:           # behind the camera: the stage needs geometry, the view shows only the dome
        add_quad(stage, "/World/Quad", 0.15, 0.15, material=mat, translate=tuple(view * -4.0))
    stage.GetRootLayer().Save()
    return path


@pytest.mark.parametrize("yaw,pitch", [(30.0, 0.0), (100.0, 35.0), (-120.0, -50.0)])
def test_the_dome_seen_at_the_image_centre_is_where_usd_points_the_camera(scene_path, yaw, pitch):
    """Centre pixel = the map at the camera's view direction (USD's transform of -Z): longitude
    atan2(x, z) at s = 0.5 - lon / 2 pi, latitude asin(y) at t = 0.5 + lat / pi (OpenEXR latlong)."""
    path = _dome_stage(scene_path(), yaw, pitch)
    stage = Usd.Stage.Open(path)
    cam = stage.GetPrimAtPath("/World/Cam")
    d = UsdGeom.Xformable(cam).ComputeLocalToWorldTransform(Usd.TimeCode(1)).TransformDir(Gf.Vec3d(0, 0, -1))
    d = np.array(d) / np.linalg.norm(np.array(d))
    s = 0.5 - np.arctan2(d[0], d[2]) / (2 * np.pi)
    t = 0.5 + np.arcsin(d[1]) / np.pi
    r = wb.render(path, frame=1, method="accumulation", samples=1, resolution=(33, 33))
    centre = r.rgba[16, 16]
    assert centre[0] == pytest.approx(srgb_to_linear(np.array([s]))[0], abs=0.015)
    assert centre[1] == pytest.approx(srgb_to_linear(np.array([t]))[0], abs=0.015)
    assert centre[3] == 0.0


def test_sh_irradiance_matches_a_brute_force_integral():
    """E(n) of a sky-over-ground map (bright above the horizon) from 9 SH coefficients against the
    integral of L cos over the hemisphere around n; a uniform map gives pi L exactly."""
    h, w = 32, 64
    d, omega = latlong_directions(w, h)
    assert omega.sum() == pytest.approx(4 * np.pi, rel=1e-3)
    radiance = np.where(d[..., 1:2] > 0, np.array([1.0, 0.8, 0.5]), np.array([0.1, 0.2, 0.05]))
    coeffs, mean = irradiance_sh(radiance)
    uniform, _ = irradiance_sh(np.ones((h, w, 3)))
    rng = np.random.default_rng(3)
    normals = rng.normal(size=(20, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    approx = sh_basis(normals) @ coeffs
    cos = np.clip(normals @ d.reshape(-1, 3).T, 0, None) * omega.reshape(1, -1)     # (20, N)
    exact = cos @ radiance.reshape(-1, 3)
    assert np.abs(approx - exact).max() < 0.05 * np.pi
    np.testing.assert_allclose(sh_basis(normals) @ uniform, np.pi, rtol=2e-3)
    assert mean == pytest.approx(np.array([0.55, 0.5, 0.275]), abs=0.01)


def test_every_method_renders_a_textured_dome_alike(scene_path):
    """A lit-by-the-dome quad moving in front of a textured dome: analytic, stochastic and the
    velocity method against accumulation (background and dome ambient)."""
    path = _dome_stage(scene_path(), 60.0, 20.0, with_quad=True)
    kw = dict(frame=1, resolution=(48, 48))
    ref = wb.render(path, method="accumulation", samples=64, **kw).rgba
    assert (ref[..., 3] > 0).any() and ref[..., 3].min() == 0.0
    for method, tol in (("analytic", 0.01), ("stochastic", 0.02), ("velocity", 0.05)):
        got = wb.render(path, method=method, samples=16, **kw).rgba
        assert rmse(got, ref) < tol, method
    lit = ref[ref[..., 3] > 0.999, :2]   # the map has no blue
    assert len(lit) and lit.min() > 0.05, "the dome lights the diffuse quad"


def _sine_map(folder: str, w: int = 512, h: int = 64, periods: int = 8) -> tuple[str, np.ndarray]:
    """A latlong map whose red is 0.5 + 0.5 sin(2 pi periods s) (8-bit sRGB), and its linear row."""
    s = (np.arange(w) + 0.5) / w
    red = np.round((0.5 + 0.5 * np.sin(2 * np.pi * periods * s)) * 255).astype(np.uint8)
    img = np.zeros((h, w, 3), np.uint8)
    img[..., 0] = red[None, :]
    Image.fromarray(img).save(os.path.join(folder, "sine_dome.png"))
    return "./sine_dome.png", srgb_to_linear(red / 255.0)


def _turning_dome(path: str, w: int) -> tuple[str, np.ndarray]:
    """(stage, centre-row red it must show): the camera yaws 100° -> 140° over the shutter in front
    of the sine dome; the expected row is the mean over 256 instants of the map (bilinear, linear
    texels) at USD's camera ray directions (Gf.Frustum.ComputePickRay)."""
    _dome_stage(path, 0.0, 0.0)
    image, row = _sine_map(os.path.dirname(path))
    stage = Usd.Stage.Open(path)
    UsdLux.DomeLight(stage.GetPrimAtPath("/World/Dome")).GetTextureFileAttr().Set(Sdf.AssetPath(image))
    rot = stage.GetPrimAtPath("/World/Cam").GetAttribute("xformOp:rotateY")
    rot.Clear()
    rot.Set(100.0, Usd.TimeCode(0.5))
    rot.Set(140.0, Usd.TimeCode(1.5))
    stage.GetRootLayer().Save()
    cam = UsdGeom.Camera(stage.GetPrimAtPath("/World/Cam"))
    want = np.zeros(w)
    for t in 0.5 + (np.arange(256) + 0.5) / 256:
        frustum = cam.GetCamera(Usd.TimeCode(float(t))).frustum
        for x in range(w):
            d = np.array(frustum.ComputePickRay(Gf.Vec2d(2 * (x + 0.5) / w - 1, 0.0)).direction)
            texel = ((0.5 - np.arctan2(d[0], d[2]) / (2 * np.pi)) % 1.0) * len(row) - 0.5
            i0, f = int(np.floor(texel)), texel - np.floor(texel)
            want[x] += ((1 - f) * row[i0 % len(row)] + f * row[(i0 + 1) % len(row)]) / 256
    return path, want


@pytest.mark.parametrize("method,kw,tol", [("accumulation", {"samples": 64}, 0.002),
                                           ("stochastic", {"samples": 64}, 0.002),
                                           ("analytic", {}, 0.002),
                                           ("analytic", {"time_bits": 0}, 0.002)])
def test_a_turning_camera_sweeps_the_dome(scene_path, method, kw, tol):
    """The camera yaws 40° over the shutter in front of a dome whose red is a sine of longitude
    (period 45°): each pixel's background is the map averaged along the arc its ray sweeps
    (_turning_dome's closed form); the sharp centre instant is far from it."""
    w = 33
    path, want = _turning_dome(scene_path(), w)
    got = wb.render(path, frame=1, method=method, resolution=(w, w), **kw).rgba[16, :, 0]
    sharp = wb.render(path, frame=1, method=method, resolution=(w, w), shutter=(0.0, 0.0), **kw).rgba[16, :, 0]
    assert np.abs(got - want).max() < tol, (method, np.round(got - want, 4))
    assert np.abs(sharp - want).max() > 0.1


def test_the_velocity_method_blurs_the_dome_with_the_camera_turn(scene_path):
    """Where nothing is hit, the velocity method's motion is the camera's turn of the pixel's ray
    direction: its centre row is clearly nearer the swept dome than its sharp instant is."""
    w = 33
    path, want = _turning_dome(scene_path(), w)
    got = wb.render(path, frame=1, method="velocity", resolution=(w, w)).rgba[16, :, 0]
    sharp = wb.render(path, frame=1, method="velocity", resolution=(w, w), shutter=(0.0, 0.0)).rgba[16, :, 0]
    assert rmse(got, want) < 0.75 * rmse(sharp, want)


def test_an_openexr_dome_is_read_linear_and_beyond_one(scene_path):
    """A half-float EXR latlong map (red 4 s, green t: HDR, linear as stored) lights the background
    as the PNG map does, without sRGB decoding: the centre pixel is 4 s, t at USD's view direction."""
    import OpenEXR
    path = _dome_stage(scene_path(), 100.0, 20.0)
    w, h = 512, 256
    s = (np.arange(w) + 0.5) / w
    t = 1.0 - (np.arange(h) + 0.5) / h
    rgb = np.zeros((h, w, 3), np.float16)
    rgb[..., 0] = 4.0 * s[None, :]
    rgb[..., 1] = t[:, None]
    with OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}, {"RGB": rgb}) as f:
        f.write(os.path.join(os.path.dirname(path), "hdr_dome.exr"))
    stage = Usd.Stage.Open(path)
    UsdLux.DomeLight(stage.GetPrimAtPath("/World/Dome")).GetTextureFileAttr().Set(Sdf.AssetPath("./hdr_dome.exr"))
    stage.GetRootLayer().Save()
    cam = stage.GetPrimAtPath("/World/Cam")
    d = UsdGeom.Xformable(cam).ComputeLocalToWorldTransform(Usd.TimeCode(1)).TransformDir(Gf.Vec3d(0, 0, -1))
    d = np.array(d) / np.linalg.norm(np.array(d))
    r = wb.render(path, frame=1, method="accumulation", samples=1, resolution=(33, 33))
    assert not r.stats["warnings"]
    centre = r.rgba[16, 16]
    assert centre[0] == pytest.approx(4.0 * (0.5 - np.arctan2(d[0], d[2]) / (2 * np.pi)), abs=0.02)
    assert centre[1] == pytest.approx(0.5 + np.arcsin(d[1]) / np.pi, abs=0.01)
