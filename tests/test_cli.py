"""CLI per SPEC §6: frame specs, # patterns, exit codes, one-line errors, no partial outputs."""

import os
import subprocess
import sys

import pytest
from scenes import emissive_quad_stage

from warp_blur.tools.cli import main
from warp_blur.core.errors import UserError
from warp_blur.output.files import read_exr
from warp_blur.usd.stage import output_path_for_frame, parse_frames


def _run(*args):
    p = subprocess.run([sys.executable, "-m", "warp_blur", *args], capture_output=True, text=True, timeout=300)
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


def test_unexposed_frame_writes_the_layers_asked_for(tmp_path, scene_path):
    """close < open: a black frame (SPEC §2) whose EXR still holds Z (inf) and motion (0)."""
    path = emissive_quad_stage(scene_path())
    out = str(tmp_path / "black.exr")
    assert main(["render", path, "-o", out, "--resolution", "16x12", "--samples", "2", "--shutter", "0.5:-0.5",
                 "--aov", "Z,motion", "--quiet"]) == 0
    ch = read_exr(out)
    assert not ch["RGBA"].any()
    assert (ch["Z"] == float("inf")).all() and not ch["motion.X"].any() and not ch["motion.Y"].any()


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


# ------------------------------------------------------------------ the CLI as a manual (issue 16)
def _subparsers():
    import argparse

    from warp_blur.tools.cli import _build_parser
    parser = _build_parser()
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return action.choices


def test_every_flag_has_help_and_shows_its_default():
    import argparse
    for name, sub in _subparsers().items():
        text = sub.format_help()
        for action in sub._actions:
            if isinstance(action, argparse._HelpAction) or action.help == argparse.SUPPRESS:
                continue
            assert action.help, f"{name} {action.option_strings or action.dest} has no help text"
            if action.option_strings and action.default not in (None, False, "", argparse.SUPPRESS):
                assert f"(default: {action.default})" in " ".join(text.split()), \
                    f"{name} {action.option_strings[0]} does not show its default {action.default!r}"
    render_help = _subparsers()["render"].format_help()
    for group in ("frames:", "camera:", "image:", "method and quality:", "shadows:", "output:", "execution and farm:"):
        assert f"\n{group}\n" in render_help
    assert "(here: cpu" in " ".join(render_help.split())
    for default in ("default 64", "default 128", "default 0"):   # method-dependent defaults spelt out
        assert default in " ".join(render_help.split())


def test_version():
    code, out, _ = _run("--version")
    assert code == 0 and out.startswith("warp-blur 0.1.0 (warp-lang ")


def test_a_single_frame_ends_with_a_line_naming_the_file(tmp_path, scene_path):
    out = tmp_path / "one.exr"
    code, stdout, stderr = _run("render", emissive_quad_stage(scene_path()), "-o", str(out), "--frame", "1",
                                "--resolution", "16x12", "--samples", "2")
    lines = [ln for ln in stdout.splitlines() if ln.strip()]
    assert code == 0 and len(lines) == 1 and lines[0].startswith(f"wrote {out} in ") and lines[0].endswith(" s")
    assert "band" not in stderr   # stdout is not a terminal: no progress bar
    code, stdout, _ = _run("render", emissive_quad_stage(scene_path()), "-o", str(out), "--frame", "1",
                           "--resolution", "16x12", "--samples", "2", "--quiet")
    assert code == 0 and stdout == ""


def test_a_single_frame_shows_its_progress_on_a_terminal(tmp_path, scene_path):
    """Under a pseudo-terminal the frame's stages and bands are drawn as a bar on stderr."""
    import pty
    out = tmp_path / "one.exr"
    scene = emissive_quad_stage(scene_path(), translate_samples={0: (-1, 0, 0), 2: (1, 0, 0)})
    master, slave = pty.openpty()
    p = subprocess.Popen([sys.executable, "-m", "warp_blur", "render", scene, "-o", str(out), "--frame", "1",
                          "--resolution", "64x48", "--samples", "4", "--threads", "2", "--method", "stochastic"],
                         stdout=slave, stderr=subprocess.PIPE, text=True)
    os.close(slave)
    chunks = []
    while True:
        try:
            data = os.read(master, 4096)
        except OSError:
            break
        if not data:
            break
        chunks.append(data.decode(errors="replace"))
    _, stderr = p.communicate(timeout=300)
    os.close(master)
    assert p.returncode == 0 and "bands" in stderr and "wrote " in "".join(chunks)
