"""EXR round trip with AOVs and metadata; atomic writes; PNG previews."""

import json
import os

import numpy as np
import pytest

from warp_blur.api import RenderResult
from warp_blur.core.errors import UserError
from warp_blur.output.files import read_exr, write_exr, write_image


def _result():
    rng = np.random.default_rng(0)
    rgba = rng.random((12, 16, 4)).astype(np.float32)
    z = rng.random((12, 16)).astype(np.float32) * 10
    z[0, 0] = np.inf
    motion = rng.normal(size=(12, 16, 2)).astype(np.float32)
    return RenderResult(rgba=rgba, aovs={"Z": z, "motion": motion}, metadata={"camera": "/World/Cam", "shutter": [0.5, 1.5]})


def test_exr_round_trip(tmp_path):
    res = _result()
    p = str(tmp_path / "a.exr")
    write_exr(p, res)
    back = read_exr(p)
    np.testing.assert_array_equal(back["RGBA"], res.rgba)
    np.testing.assert_array_equal(back["Z"], res.aovs["Z"])
    np.testing.assert_array_equal(back["motion.X"], res.aovs["motion"][..., 0])
    np.testing.assert_array_equal(back["motion.Y"], res.aovs["motion"][..., 1])
    assert back["__header__"]["warp_blur.camera"] == "/World/Cam"
    assert json.loads(back["__header__"]["warp_blur.shutter"]) == [0.5, 1.5]
    assert os.listdir(tmp_path) == ["a.exr"]  # no temporary left behind


def test_output_under_a_regular_file_is_a_user_error(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(UserError, match="is a file"):
        write_exr(str(blocker / "sub" / "a.exr"), _result())


def test_failed_write_leaves_nothing(tmp_path, monkeypatch):
    import OpenEXR

    class Boom:
        def __init__(self, *a, **k):
            pass

        def __enter__(self):
            return self

        def __exit__(self, *a):
            return False

        def write(self, path):
            with open(path, "wb") as f:
                f.write(b"partial")
            raise OSError(28, "No space left on device")

    monkeypatch.setattr(OpenEXR, "File", Boom)
    with pytest.raises(UserError, match="No space left"):
        write_exr(str(tmp_path / "a.exr"), _result())
    assert os.listdir(tmp_path) == []


def test_png_preview(tmp_path):
    from PIL import Image
    p = str(tmp_path / "a.png")
    write_image(p, _result())
    with Image.open(p) as im:
        assert im.size == (16, 12) and im.mode == "RGB"
