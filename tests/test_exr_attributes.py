"""OpenEXR standard attributes (issue 16), read back with OpenEXR and checked against USD's own
camera (Gf.Frustum) at the shutter centre."""

import os

import numpy as np
import OpenEXR
from conftest import SCENES
from pxr import Gf, Usd, UsdGeom

import warp_blur as wb


def test_standard_attributes_read_back_and_match_usds_camera(tmp_path):
    scene = os.path.join(SCENES, "demo.usda")
    result = wb.render(scene, frame=12, method="velocity", resolution=(64, 48), shadows="off")
    path = str(tmp_path / "f.exr")
    wb.write_exr(path, result)
    with OpenEXR.File(path, header_only=True) as f:
        h = dict(f.header())
    assert h["software"] == f"warp_blur {wb.__version__}"
    assert np.allclose(h["chromaticities"], (0.64, 0.33, 0.30, 0.60, 0.15, 0.06, 0.3127, 0.3290), atol=1e-6)
    assert float(h["framesPerSecond"]) == 24.0
    assert len(h["capDate"]) == 19 and h["capDate"][4] == ":" and isinstance(h["utcOffset"], float)
    assert h["owner"] and os.path.abspath(scene) in h["comments"]
    assert h["warp_blur.scene"] == os.path.abspath(scene) and "warp_blur.settings" in h

    stage = Usd.Stage.Open(scene)
    t = float(np.mean(result.metadata["shutter"]))
    frustum = UsdGeom.Camera(stage.GetPrimAtPath(result.metadata["camera"])).GetCamera(Usd.TimeCode(t)).frustum
    view, projection = frustum.ComputeViewMatrix(), frustum.ComputeProjectionMatrix()
    rng = np.random.default_rng(3)
    for p in rng.uniform(-2, 2, size=(8, 3)):
        gp = Gf.Vec3d(*map(float, p))
        cam = view.Transform(gp)                                       # USD: looking down -z
        c = np.r_[p, 1.0] @ h["worldToCamera"].astype(np.float64)
        assert np.allclose(c[:3], (cam[0], cam[1], -cam[2]), atol=1e-4)   # OpenEXR: left-handed, +z ahead
        ndc = projection.Transform(cam)                                # [-1, 1], y up (aspect 4:3 = image)
        q = np.r_[p, 1.0] @ h["worldToNDC"].astype(np.float64)
        assert np.allclose(q[:2] / q[3], ((ndc[0] + 1) / 2, (1 - ndc[1]) / 2), atol=1e-5)
