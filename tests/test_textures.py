"""Textures on UsdPreviewSurface: host decoding and mips, and closed forms through every method."""

import os

import numpy as np
import pytest
from authoring import add_camera, add_quad, add_textured_material, new_stage, set_st
from PIL import Image

import warp_blur as wb
from warp_blur.usd.textures import mip_chain, srgb_to_linear

W, H = 96, 64


def _textured_quad_stage(path: str, image: np.ndarray, translate_samples=None, **material) -> str:
    """A 4×2 quad (s across x, t up y) filling most of the view, emissive from `image` (8-bit)."""
    folder = os.path.dirname(path)
    Image.fromarray(image).save(os.path.join(folder, "tex.png"))
    stage = new_stage(path)
    add_camera(stage, translate=(0, 0, 8), focal=24.0, haperture=36.0, vaperture=24.0)
    mat = add_textured_material(stage, "/World/Looks/Tex", "./tex.png", **material)
    quad = add_quad(stage, "/World/Quad", 2.0, 1.0, material=mat, translate=None if translate_samples else (0, 0, 0),
                    translate_samples=translate_samples)
    set_st(quad, [(0, 0), (1, 0), (1, 1), (0, 1)])
    stage.GetRootLayer().Save()
    return path


def test_srgb_decoding_and_mips():
    assert srgb_to_linear(np.array([0.0, 1.0]))[1] == pytest.approx(1.0)
    assert srgb_to_linear(np.array([0.5]))[0] == pytest.approx(0.21404, abs=1e-4)
    img = np.random.default_rng(1).random((8, 6, 4)).astype(np.float32)
    chain = mip_chain(img)
    assert [lev.shape[:2] for lev in chain] == [(8, 6), (4, 3), (2, 1), (1, 1)]
    np.testing.assert_allclose(chain[1][0, 0], img[:2, :2].mean(axis=(0, 1)), rtol=1e-6)


def test_a_static_ramp_texture_reads_its_coordinate(scene_path):
    """An s ramp (raw colour space) seen head-on: each pixel shows the s of its centre."""
    ramp = np.repeat(np.arange(256, dtype=np.uint8)[None, :, None], 4, axis=0).repeat(3, axis=2)
    path = _textured_quad_stage(scene_path(), ramp)
    r = wb.render(path, frame=1, method="accumulation", samples=1, resolution=(W, H), shutter=(0.0, 0.0))
    row = r.rgba[H // 2, :, 0]
    inside = r.rgba[H // 2, :, 3] > 0.999
    xs = np.nonzero(inside)[0][2:-2]
    # s is linear in screen x on a plane facing the camera: the ramp's values fit a line
    fit = np.polyfit(xs, row[xs], 1)
    assert np.abs(np.polyval(fit, xs) - row[xs]).max() < 0.01
    assert row[xs[0]] < 0.1 and row[xs[-1]] > 0.9


def test_srgb_texture_is_made_linear(scene_path):
    grey = np.full((4, 4, 3), 128, np.uint8)
    r = wb.render(_textured_quad_stage(scene_path(), grey, color_space="sRGB"), frame=1, samples=1,
                  resolution=(32, 24), shutter=(0.0, 0.0))
    assert r.rgba[12, 16, 0] == pytest.approx(srgb_to_linear(np.array([128 / 255]))[0], abs=2e-3)


@pytest.mark.parametrize("method,kw,tol", [("analytic", {"time_bits": 0, "samples": 64}, 0.01),
                                           ("accumulation", {"samples": 128}, 0.01),
                                           ("stochastic", {"samples": 256}, 0.03)])
def test_a_moving_step_texture_blurs_as_its_box_convolution(scene_path, method, kw, tol):
    """A black|white step texture on a quad moving right by 2 units over the shutter: a pixel at
    world x (on the quad plane) sees white for the fraction clamp((x + 1) / 2, 0, 1) of the
    shutter (the step is at the quad's centre, which moves from -1 to 1): the texture convolved
    with the box of its motion. World x per pixel comes from a still ramp render."""
    step = np.zeros((4, 512, 3), np.uint8)
    step[:, 256:] = 255
    moving = _textured_quad_stage(scene_path(), step, translate_samples={0.5: (-1, 0, 0), 1.5: (1, 0, 0)})
    r = wb.render(moving, frame=1, method=method, resolution=(W, H), **kw)
    ramp = np.repeat(np.arange(256, dtype=np.uint8)[None, :, None], 4, axis=0).repeat(3, axis=2)
    still = wb.render(_textured_quad_stage(scene_path(), ramp), frame=1, samples=1, resolution=(W, H),
                      shutter=(0.0, 0.0))
    s = still.rgba[H // 2, :, 0]
    inside = still.rgba[H // 2, :, 3] > 0.999
    x_world = 4.0 * s - 2.0                            # s = (x + 2) / 4 on the still quad
    expected = np.clip((x_world + 1.0) / 2.0, 0.0, 1.0)
    cols = np.nonzero(inside)[0]
    cols = cols[(x_world[cols] > -0.9) & (x_world[cols] < 0.9)]   # covered all shutter long
    got = r.rgba[H // 2, cols, 0]
    assert np.abs(got - expected[cols]).max() < tol
    ramp_cols = cols[(expected[cols] > 0.1) & (expected[cols] < 0.9)]
    assert len(ramp_cols) >= 8, "the blur spans many pixels"


def test_every_method_reads_the_texture(scene_path):
    step = np.zeros((4, 512, 3), np.uint8)
    step[:, 256:] = 255
    path = _textured_quad_stage(scene_path(), step, translate_samples={0.5: (-0.5, 0, 0), 1.5: (0.5, 0, 0)})
    for method in ("accumulation", "stochastic", "analytic", "velocity"):
        r = wb.render(path, frame=1, method=method, samples=8, resolution=(48, 32))
        row = r.rgba[16, :, 0]
        assert row.max() > 0.9 and row[r.rgba[16, :, 3] > 0.999].min() < 0.1, method


def _udim_quad_stage(path: str, tiles: dict, t_max: float) -> str:
    """A still 4x3 quad seen whole by a sharp camera, reading `./tile.<UDIM>.png` with s over
    [0, 2] and t over [0, t_max]; `tiles` maps tile ids to the rgb (0-255) of the 8x8 images
    written beside the stage; missing tiles show the node's fallback (0.5 grey)."""
    from pxr import Gf, Sdf, UsdShade
    folder = os.path.dirname(path)
    for tile, rgb in tiles.items():
        Image.fromarray(np.full((8, 8, 3), rgb, np.uint8)).save(os.path.join(folder, f"tile.{tile}.png"))
    stage = new_stage(path)
    add_camera(stage, translate=(0, 0, 8), focal=24.0, haperture=36.0, vaperture=24.0, shutter=(0.0, 0.0))
    mat = add_textured_material(stage, "/World/Looks/Tex", "./tile.<UDIM>.png")
    UsdShade.Shader.Get(stage, "/World/Looks/Tex/Texture").CreateInput(
        "fallback", Sdf.ValueTypeNames.Float4).Set(Gf.Vec4f(0.5, 0.5, 0.5, 1.0))
    quad = add_quad(stage, "/World/Quad", 2.0, 1.5, material=mat, translate=(0, 0, 0))
    set_st(quad, [(0, 0), (2, 0), (2, t_max), (0, t_max)])
    stage.GetRootLayer().Save()
    return path


def test_udim_tiles_are_read_by_their_texture_coordinates(scene_path):
    """A quad with s over [0, 2] and t over [0, 2] reads tile 1001 (red) at the bottom left, 1002
    (green) bottom right, 1011 (blue) top left; 1012 is missing and shows the node's fallback."""
    path = _udim_quad_stage(scene_path(), {1001: (255, 0, 0), 1002: (0, 255, 0), 1011: (0, 0, 255)}, 2.0)
    for method in ("accumulation", "analytic"):
        r = wb.render(path, frame=1, method=method, samples=1, resolution=(W, H), shutter=(0.0, 0.0))
        # the quad spans columns 32..64 and rows 20..44; sample each quarter's middle
        cells = {"bl": r.rgba[38, 40, :3], "br": r.rgba[38, 56, :3], "tl": r.rgba[26, 40, :3],
                 "tr": r.rgba[26, 56, :3]}
        np.testing.assert_allclose(cells["bl"], (1, 0, 0), atol=1e-3, err_msg=method)
        np.testing.assert_allclose(cells["br"], (0, 1, 0), atol=1e-3, err_msg=method)
        np.testing.assert_allclose(cells["tl"], (0, 0, 1), atol=1e-3, err_msg=method)
        np.testing.assert_allclose(cells["tr"], (0.5, 0.5, 0.5), atol=1e-3, err_msg=method)


def test_a_renderer_shows_a_udim_tile_added_between_frames(scene_path):
    """A Renderer keeps its material table across frames; a UDIM tile written beside the tiles
    it found (1002, where the quad showed the node's fallback) is read at the next frame."""
    path = _udim_quad_stage(scene_path(), {1001: (255, 0, 0)}, 1.0)
    folder = os.path.dirname(path)
    r = wb.Renderer(path, resolution=(W, H), settings=wb.RenderSettings(method="analytic", aovs=()))
    before = r.render(1.0).rgba
    np.testing.assert_allclose(before[32, 40, :3], (1, 0, 0), atol=1e-3)
    np.testing.assert_allclose(before[32, 56, :3], (0.5, 0.5, 0.5), atol=1e-3)
    again = r.render(1.0).rgba
    assert r.materials.reused >= 1   # nothing changed: the table was kept
    np.testing.assert_array_equal(again, before)
    Image.fromarray(np.full((8, 8, 3), (0, 255, 0), np.uint8)).save(os.path.join(folder, "tile.1002.png"))
    after = r.render(1.0).rgba
    np.testing.assert_allclose(after[32, 40, :3], (1, 0, 0), atol=1e-3)
    np.testing.assert_allclose(after[32, 56, :3], (0, 1, 0), atol=1e-3)


def _transformed_step_stage(path: str, nodes) -> str:
    """A 4×2 emissive quad (s = (x + 2) / 4, t = (y + 1) / 2, from primvar `uvs`) reading a step
    texture (0 for s < 0.5, 1 above, repeating) through UsdTransform2d nodes, `nodes` listed
    from the reader to the texture as (scale, rotation, translation)."""
    from pxr import Gf, Sdf, UsdShade
    folder = os.path.dirname(path)
    step = np.zeros((4, 512, 3), np.uint8)
    step[:, 256:] = 255
    Image.fromarray(step).save(os.path.join(folder, "step.png"))
    stage = new_stage(path)
    add_camera(stage, translate=(0, 0, 8), focal=24.0, haperture=36.0, vaperture=24.0, shutter=(0.0, 0.0))
    mat = add_textured_material(stage, "/World/Looks/M", "./step.png", wrap="repeat", st_name="uvs")
    tex = UsdShade.Shader.Get(stage, "/World/Looks/M/Texture")
    source = UsdShade.Shader.Get(stage, "/World/Looks/M/StReader")
    for i, (scale, rotation, translation) in enumerate(nodes):
        node = UsdShade.Shader.Define(stage, f"/World/Looks/M/Transform{i}")
        node.CreateIdAttr("UsdTransform2d")
        node.CreateInput("in", Sdf.ValueTypeNames.Float2).ConnectToSource(source.ConnectableAPI(), "result")
        node.CreateInput("scale", Sdf.ValueTypeNames.Float2).Set(Gf.Vec2f(*scale))
        node.CreateInput("rotation", Sdf.ValueTypeNames.Float).Set(rotation)
        node.CreateInput("translation", Sdf.ValueTypeNames.Float2).Set(Gf.Vec2f(*translation))
        node.CreateOutput("result", Sdf.ValueTypeNames.Float2)
        source = node
    tex.GetInput("st").ConnectToSource(source.ConnectableAPI(), "result")
    quad = add_quad(stage, "/World/Quad", 2.0, 1.0, material=mat)
    set_st(quad, [(0, 0), (1, 0), (1, 1), (0, 1)], name="uvs")
    stage.GetRootLayer().Save()
    return path


@pytest.mark.parametrize("nodes,want", [
    ([((2, 1), 0.0, (0.25, 0))], lambda s, t: ((2 * s + 0.25) % 1.0) >= 0.5),
    ([((2, 1), 0.0, (0, 0)), ((1, 1), 0.0, (0.25, 0))], lambda s, t: ((2 * s + 0.25) % 1.0) >= 0.5),
    ([((1, 1), 0.0, (0.25, 0)), ((2, 1), 0.0, (0, 0))], lambda s, t: ((2 * s + 0.5) % 1.0) >= 0.5),
    ([((1, 1), 90.0, (0, 0))], lambda s, t: (-t % 1.0) >= 0.5),
])
def test_usd_transform2d_maps_the_texture_coordinates(scene_path, nodes, want):
    """UsdTransform2d scales, rotates counter-clockwise (degrees) and translates st, in that order;
    chained nodes apply from the reader on; the primvar is found through them. Pixel centres away
    from the step's edges read 0 or 1 as the closed form says."""
    path = _transformed_step_stage(scene_path(), nodes)
    red = wb.render(path, frame=1, method="accumulation", samples=1, resolution=(96, 64)).rgba[..., 0]
    rows, cols = np.arange(25, 39), np.arange(33, 63)          # inside the quad (rows 24..39, cols 32..63)
    s = (((cols + 0.5) / 8.0 - 6.0) + 2.0) / 4.0
    t = ((4.0 - (rows + 0.5) / 8.0) + 1.0) / 2.0               # y up: row 0 is y = 4
    ss, tt = np.meshgrid(s, t)
    expected = want(ss, tt).astype(float)
    got = red[np.ix_(rows, cols)]
    # pixels within 1/64 (in st') of a step edge may be filtered: leave them out
    edge = np.zeros_like(expected, bool)
    for dx, dy in ((1, 0), (-1, 0), (0, 1), (0, -1)):
        edge |= want(ss + dx / 64.0, tt + dy / 64.0).astype(float) != expected
    assert (~edge).sum() > 200
    np.testing.assert_allclose(got[~edge], expected[~edge], atol=0.02)


def test_openexr_images_decode_grey_rgba_and_non_finite_values(tmp_path):
    """EXR textures: a Y-only image becomes grey with alpha 1; NaN reads 0 and inf the largest
    half float, so no non-finite value reaches a kernel."""
    import OpenEXR

    from warp_blur.usd.textures import EXR_MAGIC, _exr_rgba
    y = np.array([[0.25, np.nan], [np.inf, 3.0]], np.float32)
    path = str(tmp_path / "grey.exr")
    with OpenEXR.File({"compression": OpenEXR.NO_COMPRESSION, "type": OpenEXR.scanlineimage}, {"Y": y}) as f:
        f.write(path)
    with open(path, "rb") as f:
        data = f.read()
    assert data[:4] == EXR_MAGIC
    rgba = _exr_rgba(data)
    np.testing.assert_allclose(rgba[..., 0], [[0.25, 0.0], [65504.0, 3.0]])
    np.testing.assert_allclose(rgba[..., 1], rgba[..., 0])
    np.testing.assert_allclose(rgba[..., 3], 1.0)


def _texture_set(path: str):
    from warp_blur.usd.textures import TextureSet
    textures = TextureSet()
    assert textures.add_texture(path, "raw", "clamp", "clamp") is not None
    textures.add_binding(0, "rgb", (1, 1, 1, 1), (0, 0, 0, 0))
    return textures


def test_frames_reading_the_same_images_share_one_upload_and_a_changed_image_is_read_again(tmp_path):
    """Each frame builds its own TextureSet; one that reads the images of an earlier frame reuses
    its texel atlas on the device (no upload), and a rewritten image file is uploaded afresh."""
    from warp_blur.raster.device_data import texture_arrays
    path = str(tmp_path / "tex.png")
    Image.fromarray(np.full((4, 4, 3), 64, np.uint8)).save(path)
    first = texture_arrays(_texture_set(path), "cpu")
    second = texture_arrays(_texture_set(path), "cpu")
    assert second.texels is first.texels
    np.testing.assert_allclose(first.texels.numpy()[0], (64 / 255, 64 / 255, 64 / 255, 1.0), rtol=1e-6)
    Image.fromarray(np.full((8, 8, 3), 200, np.uint8)).save(path)   # new size and mtime
    third = texture_arrays(_texture_set(path), "cpu")
    assert third.texels is not first.texels
    np.testing.assert_allclose(third.texels.numpy()[0], (200 / 255, 200 / 255, 200 / 255, 1.0), rtol=1e-6)


def test_a_renderer_shows_a_texture_rewritten_between_frames(scene_path):
    path = _textured_quad_stage(scene_path(), np.full((4, 4, 3), 64, np.uint8))
    r = wb.Renderer(path, resolution=(32, 24), settings=wb.RenderSettings(method="analytic", aovs=()))
    before = r.render(1.0).rgba[12, 16, 0]
    Image.fromarray(np.full((8, 8, 3), 200, np.uint8)).save(os.path.join(os.path.dirname(path), "tex.png"))
    after = r.render(1.0).rgba[12, 16, 0]
    assert before == pytest.approx(64 / 255, abs=2e-3) and after == pytest.approx(200 / 255, abs=2e-3)


def test_roughness_and_metallic_from_one_texture_read_it_once_alike(scene_path):
    """glTF's metallic-roughness texture (roughness from g, metallic from b): both inputs read
    one texture sample per shading. The image equals the one where metallic reads a copy of the
    file (a texture of its own, read separately), bit for bit, lit by a sun."""
    from authoring import add_distant_light
    from pxr import Sdf, UsdShade
    rng = np.random.default_rng(3)
    texels = (rng.random((16, 16, 3)) * 255).astype(np.uint8)
    images = []
    for copy in (False, True):
        path = _textured_quad_stage(scene_path(), texels, input_name="roughness", output="g")
        folder = os.path.dirname(path)
        Image.fromarray(texels).save(os.path.join(folder, "tex_copy.png"))
        from pxr import Usd
        stage = Usd.Stage.Open(path)
        surface = UsdShade.Shader.Get(stage, "/World/Looks/Tex/PreviewSurface")
        surface.GetInput("diffuseColor").Set((0.6, 0.5, 0.4))
        surface.GetInput("useSpecularWorkflow").Set(0)   # the metallic workflow: metallic is read
        if copy:
            other = UsdShade.Shader.Define(stage, "/World/Looks/Tex/Copy")
            other.CreateIdAttr("UsdUVTexture")
            other.CreateInput("file", Sdf.ValueTypeNames.Asset).Set("./tex_copy.png")
            other.CreateInput("sourceColorSpace", Sdf.ValueTypeNames.Token).Set("raw")
            for wrap in ("wrapS", "wrapT"):
                other.CreateInput(wrap, Sdf.ValueTypeNames.Token).Set("clamp")
            reader = UsdShade.Shader.Get(stage, "/World/Looks/Tex/StReader")
            other.CreateInput("st", Sdf.ValueTypeNames.Float2).ConnectToSource(reader.ConnectableAPI(), "result")
            source = other
        else:
            source = UsdShade.Shader.Get(stage, "/World/Looks/Tex/Texture")
        source.CreateOutput("b", Sdf.ValueTypeNames.Float)
        surface.CreateInput("metallic", Sdf.ValueTypeNames.Float).ConnectToSource(source.ConnectableAPI(), "b")
        add_distant_light(stage, "/World/Sun", intensity=3.0, rotate=(-20, 15, 0))
        stage.GetRootLayer().Save()
        images.append(wb.render(path, frame=1, method="accumulation", samples=1, resolution=(W, H),
                                shutter=(0.0, 0.0), aovs=()).rgba)
    np.testing.assert_array_equal(images[0], images[1])
    inside = images[0][H // 2, W // 4:3 * W // 4, :3]
    assert inside.std() > 0.01   # roughness and metallic vary over the quad
