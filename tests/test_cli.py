"""CLI per SPEC §6: frame specs, # patterns, exit codes, one-line errors, no partial outputs."""

import os
import subprocess
import sys

import pytest
from scenes import emissive_quad_stage

from warp_blur.cli import main
from warp_blur.errors import UserError
from warp_blur.output import read_exr
from warp_blur.stage import output_path_for_frame, parse_frames


def _run(*args):
    p = subprocess.run([sys.executable, "-m", "warp_blur.cli", *args], capture_output=True, text=True, timeout=300)
    return p.returncode, p.stdout, p.stderr


def test_frame_specs():
    assert parse_frames("1:4") == [1, 2, 3, 4]
    assert parse_frames("1:9x4") == [1, 5, 9]
    assert parse_frames("1,5,9") == [1, 5, 9]
    for bad in ("a:b", "1:", "", "1,,2"):
        with pytest.raises(UserError):
            parse_frames(bad)


def test_output_patterns():
    assert output_path_for_frame("out/shot.####.exr", 7, 3) == "out/shot.0007.exr"
    assert output_path_for_frame("shot.###.###.exr", 1.25, 3) == "shot.001.250.exr"
    assert output_path_for_frame("single.exr", 3, 1) == "single.exr"
    with pytest.raises(UserError, match="no '#'"):
        output_path_for_frame("single.exr", 3, 2)
    with pytest.raises(UserError, match="sub-frame"):
        output_path_for_frame("shot.####.exr", 1.5, 2)


@pytest.mark.parametrize("case", ["missing", "empty_stage", "bad_frames", "bad_resolution", "zero_resolution",
                                  "syntax", "time_bits_wrong_method", "bad_camera", "not_utf8", "fifo",
                                  "usdz_not_zip", "directory"])
def test_user_errors_exit_2_with_one_line_and_no_output(tmp_path, scene_path, case):
    from authoring import new_stage
    good = emissive_quad_stage(scene_path())
    out = str(tmp_path / "out" / "f.####.exr")
    args = ["render", good, "-o", out, "--frame", "1", "--resolution", "32x24"]
    if case == "missing":
        args[1] = str(tmp_path / "nope.usda")
    elif case == "empty_stage":   # no camera and nothing to frame
        p = scene_path()
        st = new_stage(p)
        st.GetRootLayer().Save()
        args[1] = p
    elif case == "bad_frames":
        args[4:6] = ["--frames", "x:y"]
    elif case == "bad_resolution":
        args[7] = "32by24"
    elif case == "zero_resolution":
        args[7] = "0x24"
    elif case == "syntax":
        p = tmp_path / "broken.usda"
        p.write_text("#usda 1.0\ndef Xform \"W\" {\n  float x = \n")
        args[1] = str(p)
    elif case == "not_utf8":
        p = tmp_path / "bytes.usda"
        p.write_bytes(b'#usda 1.0\ndef Xform "W\xff\xfe" {\n}\n')
        args[1] = str(p)
    elif case == "fifo":
        p = tmp_path / "pipe.usda"
        os.mkfifo(p)
        args[1] = str(p)
    elif case == "usdz_not_zip":
        p = tmp_path / "fake.usdz"
        p.write_text("not a zip")
        args[1] = str(p)
    elif case == "directory":
        args[1] = str(tmp_path)
    elif case == "time_bits_wrong_method":
        args += ["--time-bits", "64"]
    elif case == "bad_camera":
        args += ["--camera", "/World/Nope"]
    code, _, err = _run(*args)
    assert code == 2, err
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("warp-blur: error:"), err
    assert "Traceback" not in err
    assert not os.path.exists(tmp_path / "out") or not os.listdir(tmp_path / "out")
    if case == "syntax":   # USD's own words say where
        assert "line 3" in lines[0], lines[0]


def test_render_frames_writes_each_frame(tmp_path, scene_path):
    path = emissive_quad_stage(scene_path(), translate_samples={0: (-1, 0, 0), 2: (1, 0, 0)})
    out = str(tmp_path / "frames" / "f.####.exr")
    assert main(["render", path, "-o", out, "--frames", "0:2", "--resolution", "32x24", "--samples", "4",
                 "--aov", "Z,motion", "--quiet"]) == 0
    assert sorted(os.listdir(tmp_path / "frames")) == ["f.0000.exr", "f.0001.exr", "f.0002.exr"]
    ch = read_exr(str(tmp_path / "frames" / "f.0001.exr"))
    assert ch["RGBA"].shape == (24, 32, 4) and "Z" in ch and "motion.X" in ch


def test_unauthored_shutter_warns(tmp_path, scene_path):
    path = emissive_quad_stage(scene_path(), shutter=None)
    code, _, err = _run("render", path, "-o", str(tmp_path / "a.exr"), "--resolution", "16x12", "--samples", "2")
    assert code == 0 and "no authored shutter" in err


def test_compare_exit_codes(tmp_path, scene_path):
    path = emissive_quad_stage(scene_path(), translate_samples={0: (-1, 0, 0), 2: (1, 0, 0)})
    a, b = str(tmp_path / "a.exr"), str(tmp_path / "b.exr")
    assert main(["render", path, "-o", a, "--frame", "1", "--resolution", "32x24", "--samples", "1", "--quiet"]) == 0
    assert main(["render", path, "-o", b, "--frame", "1", "--resolution", "32x24", "--samples", "16", "--quiet"]) == 0
    assert main(["compare", a, a, "--fail", "0"]) == 0
    assert main(["compare", a, b, "--fail", "1e-6"]) == 1
    assert main(["compare", a, str(tmp_path / "missing.exr")]) == 2
