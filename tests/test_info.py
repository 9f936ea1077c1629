"""`warp-blur info` (issue 16): object and camera motion reported apart, readable prototype names,
no traceback when its output pipe closes early."""

import os
import subprocess
import sys

from conftest import SCENES

from warp_blur.tools.info import format_report, scene_report


def test_object_and_camera_motion_are_reported_apart():
    report = scene_report(os.path.join(SCENES, "demo.usda"), frame=5, resolution=(640, 480))
    prims = {p["path"]: p for p in report["prims"]}
    ground = prims["/World/Ground"]
    assert report["camera_moves"]
    assert not ground["moves_in_world"] and ground["max_object_motion_px"] < 1e-3
    assert 1.0 < ground["max_camera_motion_px"] < 200.0      # only the camera moves it on screen
    assert prims["/World/Ball"]["moves_in_world"] and prims["/World/Ball"]["max_object_motion_px"] > 5.0
    text = format_report(report)
    assert "/World/Ground: 200 tris, still; the camera's motion moves it up to" in text


def test_prototype_names_are_readable():
    report = scene_report(os.path.join(SCENES, "demo.usda"), frame=5, resolution=(64, 48))
    paths = [p["path"] for p in report["prims"]]
    assert "/World/Ring (prototype Cone)" in paths, paths


def test_info_into_a_closed_pipe_prints_no_traceback():
    p = subprocess.run(f"'{sys.executable}' -m warp_blur.tools.cli info '{os.path.join(SCENES, 'demo.usda')}' --json | head -1",
                       shell=True, capture_output=True, text=True, timeout=300)
    assert p.stdout.strip() == "{" and "Traceback" not in p.stderr
