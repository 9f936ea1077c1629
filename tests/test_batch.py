"""Frame ranges at production shape: kill and resume to the same pixels, worker processes and a
local Dask cluster give the same images, a failing frame does not stop the others, bad input
exits 2 with one line naming the problem."""

import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from scenes import emissive_quad_stage

import warp_blur as wb
from warp_blur.tools.cli import main
from warp_blur.output.files import read_exr


def _shot(path, frames=6):
    from authoring import add_camera, add_dome, add_material, add_quad, new_stage
    stage = new_stage(path, start=1, end=frames)
    add_camera(stage)
    add_dome(stage)
    mat = add_material(stage, "/World/Looks/E", emissive=(0.9, 0.5, 0.2))
    add_quad(stage, "/World/Q", 1.0, 1.0, material=mat, translate_samples={1: (-3, 0, 0), frames: (3, 1, 0)})
    stage.GetRootLayer().Save()
    return path


def _images(folder):
    return {f: read_exr(os.path.join(folder, f))["RGBA"] for f in sorted(os.listdir(folder)) if f.endswith(".exr")}


def _cli(*args):
    return subprocess.Popen([sys.executable, "-m", "warp_blur", *args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def test_killed_run_resumes_to_identical_frames(tmp_path, scene_path):
    scene = _shot(scene_path(), frames=8)
    common = ["--frames", "1:8", "--resolution", "96x72", "--samples", "200", "--quiet"]
    assert main(["render", scene, "-o", str(tmp_path / "full" / "f.####.exr"), *common]) == 0
    out = tmp_path / "killed"
    proc = _cli("render", scene, "-o", str(out / "f.####.exr"), *common)
    deadline = time.time() + 120
    def finished() -> list[str]:   # frames under their final names (a killed write leaves a .tmp- file)
        return [f for f in os.listdir(out) if f.endswith(".exr") and not f.startswith(".tmp-")] if out.exists() else []

    while time.time() < deadline and len(finished()) < 2:
        time.sleep(0.05)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    done = finished()
    assert 2 <= len(done) < 8, "the kill should land mid-range"
    for f in done:  # what exists under a final name is complete
        assert read_exr(str(out / f))["RGBA"].shape == (72, 96, 4)
    assert main(["render", scene, "-o", str(out / "f.####.exr"), *common, "--resume"]) == 0
    full, resumed = _images(tmp_path / "full"), _images(out)
    assert sorted(full) == sorted(resumed) and len(full) == 8
    for name in full:
        np.testing.assert_array_equal(full[name], resumed[name])
    assert not [f for f in os.listdir(out) if f.startswith(".tmp-")]


def test_resume_skips_complete_frames_with_the_same_settings(tmp_path, scene_path):
    scene = _shot(scene_path())
    out = str(tmp_path / "f.####.exr")
    args = ["render", scene, "-o", out, "--frames", "1:3", "--resolution", "16x12", "--quiet"]
    assert main(args + ["--samples", "2"]) == 0
    stamp = os.path.getmtime(tmp_path / "f.0002.exr")
    assert main(args + ["--samples", "2", "--resume"]) == 0
    assert os.path.getmtime(tmp_path / "f.0002.exr") == stamp
    assert main(args + ["--samples", "3", "--resume"]) == 0  # other settings: re-rendered
    assert os.path.getmtime(tmp_path / "f.0002.exr") != stamp


def test_worker_processes_and_dask_cluster_give_the_same_images(tmp_path, scene_path):
    distributed = pytest.importorskip("distributed")
    scene = _shot(scene_path())
    common = ["--frames", "1:6", "--resolution", "32x24", "--samples", "8", "--quiet"]
    assert main(["render", scene, "-o", str(tmp_path / "serial" / "f.####.exr"), *common]) == 0
    assert main(["render", scene, "-o", str(tmp_path / "workers" / "f.####.exr"), *common, "--workers", "2"]) == 0
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None) as cl:
        assert main(["render", scene, "-o", str(tmp_path / "farm" / "f.####.exr"), *common,
                     "--cluster", cl.scheduler_address]) == 0
    serial = _images(tmp_path / "serial")
    for other in ("workers", "farm"):
        imgs = _images(tmp_path / other)
        assert sorted(imgs) == sorted(serial)
        for k in serial:
            np.testing.assert_array_equal(imgs[k], serial[k])


def test_a_failing_frame_does_not_stop_the_others(tmp_path, scene_path):
    from authoring import add_camera, add_mesh, new_stage
    path = scene_path()
    stage = new_stage(path, start=1, end=5)
    add_camera(stage, shutter=(0, 0))
    good = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]
    add_mesh(stage, "/World/T", None, [3], [0, 1, 2],
             points_samples={1: good, 2: good, 3: [(0, 0, 0), (float("nan"), 0, 0), (0, 1, 0)], 4: good, 5: good})
    stage.GetRootLayer().Save()
    out = tmp_path / "f"
    code = main(["render", path, "-o", str(out / "f.####.exr"), "--frames", "1:5", "--resolution", "16x12", "--quiet"])
    assert code == 1
    assert sorted(os.listdir(out)) == ["f.0001.exr", "f.0002.exr", "f.0004.exr", "f.0005.exr"]


def test_render_frames_api_with_progress(scene_path):
    scene = _shot(scene_path())
    seen = []
    results = list(wb.render_frames(scene, [1, 2, 3], resolution=(16, 12), settings=wb.RenderSettings(samples=2),
                                    progress=lambda done, total, f: seen.append((done, total, f))))
    assert [f for f, _ in results] == [1.0, 2.0, 3.0]
    assert seen == [(1, 3, 1.0), (2, 3, 2.0), (3, 3, 3.0)]
    assert all(r.rgba.shape == (12, 16, 4) for _, r in results)


def _stage_with(scene_path, kind):
    from authoring import add_camera, add_mesh, new_stage
    path = scene_path()
    stage = new_stage(path)
    add_camera(stage)
    if kind == "nan":
        add_mesh(stage, "/World/Bad", [(0, 0, 0), (float("inf"), 0, 0), (0, 1, 0)], [3], [0, 1, 2])
    elif kind == "indices":
        add_mesh(stage, "/World/Bad", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [3], [0, 1, 9])
    stage.GetRootLayer().Save()
    return path


@pytest.mark.parametrize("case", ["no_geometry", "nan", "indices", "outside_range", "under_a_file", "workers"])
def test_bad_input_exits_2_naming_the_problem(tmp_path, scene_path, case, capsys):
    path = emissive_quad_stage(scene_path())
    out = str(tmp_path / "o" / "f.exr")
    extra = []
    expect = ""
    if case in ("no_geometry", "nan", "indices"):
        path = _stage_with(scene_path, {"no_geometry": "", "nan": "nan", "indices": "indices"}[case])
        expect = {"no_geometry": "no renderable geometry", "nan": "/World/Bad", "indices": "/World/Bad"}[case]
    elif case == "outside_range":
        extra = ["--frame", "7"]
        expect = "outside the stage's authored range 0..2"
    elif case == "under_a_file":
        (tmp_path / "blocker").write_text("x")
        out = str(tmp_path / "blocker" / "f.exr")
        expect = "is a file"
    elif case == "workers":
        extra = ["--workers", "0"]
        expect = "--workers"
    code = main(["render", path, "-o", out, "--resolution", "16x12", "--samples", "1", *extra])
    err = capsys.readouterr().err
    assert code == 2 and expect in err, err
    assert not os.path.exists(tmp_path / "o") or not os.listdir(tmp_path / "o")


def test_skip_invalid_drops_the_prim_with_a_warning(tmp_path, scene_path, capsys):
    from authoring import add_camera, add_mesh, new_stage
    path = scene_path()
    stage = new_stage(path)
    add_camera(stage)
    add_mesh(stage, "/World/Bad", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [3], [0, 1, 9])
    add_mesh(stage, "/World/Good", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [3], [0, 1, 2])
    stage.GetRootLayer().Save()
    assert main(["render", path, "-o", str(tmp_path / "f.exr"), "--resolution", "16x12", "--samples", "1",
                 "--skip-invalid"]) == 0
    assert "dropping /World/Bad" in capsys.readouterr().err


def test_the_api_refuses_what_the_cli_refuses(tmp_path, scene_path):
    """One behaviour, two interfaces (issue 16): the same frame, the same typed error and message."""
    import contextlib
    import io

    import warp_blur as wb
    from warp_blur.tools.cli import main
    scene = emissive_quad_stage(scene_path(), translate_samples={0: (-1, 0, 0), 2: (1, 0, 0)})
    cases = [dict(frame=999.0), dict(frame=float("nan")), dict(frame=1.0, resolution=(16384, 16384), method="velocity",
                                                               frame_memory_limit_mb=64.0)]
    for case in cases:
        kw = dict(case)
        frame = kw.pop("frame")
        with pytest.raises(wb.UserError) as api_error:
            wb.render(scene, frame=frame, samples=1, **kw)
        args = ["render", scene, "-o", str(tmp_path / "x.exr"), "--frame", str(frame), "--samples", "1"]
        if "resolution" in kw:
            args += ["--resolution", "16384x16384", "--method", "velocity", "--memory-limit", "64"]
        err = io.StringIO()
        with contextlib.redirect_stderr(err):
            assert main(args) == 2
        assert err.getvalue().strip() == f"warp-blur: error: {api_error.value}"
