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


def test_info_counts_the_triangles_a_render_at_its_resolution_takes(scene_path):
    """info builds the frame's Scene with the image's projection, so spheres (and subdivision
    meshes) take the levels a render at that resolution gives them."""
    import warp_blur as wb
    from authoring import sphere_field
    path = sphere_field(scene_path(), 200)
    report = scene_report(path, frame=5, resolution=(160, 120))
    r = wb.render(path, frame=5, method="velocity", resolution=(160, 120), aovs=())
    assert report["triangles"] == r.stats["triangles"] < 200 * 1280


def test_info_leaves_out_a_prim_that_turns_non_finite_at_the_shutter_close(tmp_path):
    """info drops invalid prims with a warning; one whose transform is finite at the shutter's
    open and not at its close (the Scene asks for the frame again then) is reported, not a
    traceback."""
    text = open(os.path.join(SCENES, "rotation.usda")).read().replace(
        "double3 xformOp:translate = (2.2, -0.3, 0)",
        "double3 xformOp:translate.timeSamples = { 2.0: (2.2, -0.3, 0), 2.4: (2.2, -0.3, 0), 2.5: (nan, -0.3, 0) }")
    path = str(tmp_path / "late_nan.usda")
    with open(path, "w") as f:
        f.write(text)
    report = scene_report(path, frame=2, resolution=(64, 48))
    assert report["triangles"] > 0 and "/World/Box" in [p["path"] for p in report["prims"]]
