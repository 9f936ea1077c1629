"""The framing camera of a stage without one: checked against USD's own Gf.Frustum projection."""

import itertools

import numpy as np
import pytest
from authoring import add_mesh, new_stage
from pxr import Gf, Usd, UsdGeom

import warp_blur as wb
from warp_blur.core.errors import StageError
from warp_blur.usd.framing import FRAMING_CAMERA_PATH, place_framing_camera, stage_bounds
from warp_blur.tools.info import scene_report
from warp_blur.usd.stage import choose_camera, open_stage


def _box_stage(path: str, up: str, lo=(-3.0, 0.5, -1.0), hi=(5.0, 2.5, 2.0)) -> str:
    stage = new_stage(path, up=up)
    pts = [tuple(lo[k] if (i >> k) & 1 == 0 else hi[k] for k in range(3)) for i in range(8)]
    faces = [0, 1, 3, 2, 4, 6, 7, 5, 0, 4, 5, 1, 2, 3, 7, 6, 0, 2, 6, 4, 1, 5, 7, 3]
    add_mesh(stage, "/World/Box", pts, [4] * 6, faces)
    stage.GetRootLayer().Save()
    return path


@pytest.mark.parametrize("up", ["Y", "Z"])
def test_framing_camera_holds_the_bounds_in_view(scene_path, up):
    stage = open_stage(_box_stage(scene_path(), up))
    cam = choose_camera(stage, None)
    assert str(cam.GetPath()) == FRAMING_CAMERA_PATH
    place_framing_camera(stage, cam, 1.0, 4 / 3)
    gf = cam.GetCamera(Usd.TimeCode(1.0))
    gf.horizontalAperture = max(gf.horizontalAperture, gf.verticalAperture * 4 / 3)   # expandAperture
    gf.verticalAperture = gf.horizontalAperture * 3 / 4
    vp = gf.frustum.ComputeViewMatrix() * gf.frustum.ComputeProjectionMatrix()
    box = stage_bounds(stage, 1.0)
    ndc = []
    near, far = gf.clippingRange.min, gf.clippingRange.max
    view = gf.frustum.ComputeViewMatrix()
    for corner in itertools.product(*zip(box.GetMin(), box.GetMax())):
        p = vp.Transform(Gf.Vec3d(*corner))
        ndc.append((p[0], p[1]))
        depth = -view.Transform(Gf.Vec3d(*corner))[2]
        assert near < depth < far, "the clipping range holds the whole bounds"
    ndc = np.abs(np.array(ndc))
    assert ndc.max() <= 1.0, "every corner of the bounds is in view"
    assert ndc.max() > 0.5, "the bounds fill a good part of the frame"
    forward = np.array(gf.frustum.ComputeViewDirection())
    expected = [0, 1, 0] if up == "Z" else [0, 0, -1]
    np.testing.assert_allclose(forward, expected, atol=1e-9)
    up_vec = np.array(gf.frustum.ComputeUpVector())
    np.testing.assert_allclose(up_vec, [0, 0, 1] if up == "Z" else [0, 1, 0], atol=1e-9)


def test_a_stage_without_camera_renders_through_the_framing_camera(scene_path):
    path = _box_stage(scene_path(), "Y")
    result = wb.render(path, frame=1, method="accumulation", samples=1, resolution=(64, 48))
    assert result.metadata["camera"] == FRAMING_CAMERA_PATH
    assert any("computed camera" in w for w in result.stats["warnings"])
    alpha = result.rgba[..., 3]
    assert alpha.mean() > 0.1 and alpha[0].max() == 0 and alpha[-1].max() == 0   # in view, not cropped
    report = scene_report(path, resolution=(64, 48))
    assert report["camera_computed"] and report["camera"] == FRAMING_CAMERA_PATH
    with open(path) as f:
        assert "WarpBlurFramingCamera" not in f.read(), "the file on disk is never edited"


def test_a_missing_named_camera_stays_an_error(scene_path):
    path = _box_stage(scene_path(), "Y")
    with pytest.raises(StageError, match="not found"):
        wb.render(path, frame=1, camera="/World/NoSuchCam", resolution=(32, 24))


def test_unframeable_geometry_reports_what_is_wrong_with_it(scene_path):
    """An instancer whose indices leave its prototypes has no bounds (USD's BBoxCache gives none):
    the error names the instancer, not a missing camera; an empty stage stays a framing error."""
    stage = new_stage(scene_path())
    inst = UsdGeom.PointInstancer.Define(stage, "/World/Inst")
    UsdGeom.Cube.Define(stage, "/World/Inst/Proto")
    inst.CreatePrototypesRel().SetTargets(["/World/Inst/Proto"])
    inst.CreateProtoIndicesAttr([0, 5])
    inst.CreatePositionsAttr([(0, 0, 0), (2, 0, 0)])
    stage.GetRootLayer().Save()
    path = stage.GetRootLayer().realPath
    with pytest.raises(StageError, match="/World/Inst.*protoIndices"):
        wb.render(path, frame=1, resolution=(32, 24))
    empty = new_stage(scene_path())
    UsdGeom.Xform.Define(empty, "/World")
    empty.GetRootLayer().Save()
    with pytest.raises(StageError, match="no geometry to frame"):
        wb.render(empty.GetRootLayer().realPath, frame=1, resolution=(32, 24))


def test_each_camera_less_stage_says_it_is_framed(scene_path):
    """The framing camera's warning is said once per Renderer, not once per process: a pipeline
    rendering many camera-less assets in one process hears it for each, and each result's stats
    say it, the same stage opened again included (it used to be said once per stage and process,
    so a second render of it reported nothing); a Renderer's later frames do not repeat it (and
    this file's tests do not depend on which ran first)."""
    first, second = _box_stage(scene_path(), "Y"), _box_stage(scene_path(), "Z")
    heard = []
    for path in (first, second, first):
        result = wb.render(path, frame=1, method="accumulation", samples=1, resolution=(32, 24))
        heard.append(sum("computed camera" in w for w in result.stats["warnings"]))
    assert heard == [1, 1, 1]
    renderer = wb.Renderer(first, resolution=(32, 24), settings=wb.RenderSettings(method="accumulation", samples=1))
    assert [sum("computed camera" in w for w in renderer.render(f).stats["warnings"]) for f in (1, 2)] == [1, 0]


def test_a_renderers_warnings_are_its_own_whichever_renders_first(scene_path):
    """Two Renderers of camera-less stages made one after the other and rendered in the other
    order: each frame's stats hold its own stage's computed-camera warning, once (the second
    Renderer's frame used to report both, the first's none); a frame that fails keeps them for
    the next frame that renders."""
    first = wb.Renderer(_box_stage(scene_path(), "Y"), resolution=(32, 24),
                        settings=wb.RenderSettings(method="accumulation", samples=1))
    second = wb.Renderer(_box_stage(scene_path(), "Z"), resolution=(32, 24),
                         settings=wb.RenderSettings(method="accumulation", samples=1))

    def heard(result):
        return sum("computed camera" in w for w in result.stats["warnings"])
    assert heard(second.render(1)) == 1
    with pytest.raises(wb.UserError):
        first.render(float("nan"))
    assert heard(first.render(1)) == 1
    assert heard(first.render(1)) == 0
