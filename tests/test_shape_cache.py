"""usd/shape_cache.py: implicit gprims' tessellations kept on disk are trimesh's arrays, and a
later process gets them without importing trimesh."""

import os
import subprocess
import sys

import numpy as np
import pytest

from warp_blur.usd import shape_cache
from warp_blur.usd.tessellate import _make_trimesh_shape, _trimesh_axis_rotation

SHAPES = [("sphere", 1.0, 0.0, "Z", 3), ("sphere", 0.25, 0.0, "Z", 1), ("cylinder", 1.0, 2.0, "X", 0),
          ("cone", 0.5, 3.0, "Y", 0), ("capsule", 0.3, 1.5, "Z", 0)]


@pytest.fixture
def folder(tmp_path, monkeypatch):
    monkeypatch.setattr(shape_cache, "_folder", lambda: str(tmp_path / "shapes"))
    return tmp_path / "shapes"


def test_kept_arrays_are_trimeshs_bit_for_bit(folder):
    for shape in SHAPES:
        key = f"test {shape}"
        made = shape_cache.cached_arrays(key, lambda: _make_trimesh_shape(*shape))
        kept = shape_cache.cached_arrays(key, lambda: pytest.fail("made again"))
        for a, b, c in zip(made, kept, _make_trimesh_shape(*shape)):
            assert a.dtype == b.dtype == c.dtype and np.array_equal(a, b) and np.array_equal(a, c)
    assert len(os.listdir(folder)) >= len(SHAPES)   # (and the axis rotations the shapes use)


def test_a_damaged_or_unwritable_cache_only_costs_the_making(folder, tmp_path, monkeypatch):
    want = _trimesh_axis_rotation("X")
    shape_cache.cached_arrays("rot", lambda: (want,))
    (path,) = folder.iterdir()
    path.write_bytes(path.read_bytes()[:40])          # a truncated file
    got = shape_cache.cached_arrays("rot", lambda: (want,))[0]
    assert np.array_equal(got, want)
    assert np.array_equal(shape_cache.cached_arrays("rot", lambda: pytest.fail("made again"))[0], want)
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    monkeypatch.setattr(shape_cache, "_folder", lambda: str(blocker / "shapes"))   # cannot be made
    assert np.array_equal(shape_cache.cached_arrays("rot", lambda: (want,))[0], want)


def test_a_later_process_renders_spheres_without_importing_trimesh(tmp_path):
    """Two processes render a stage of spheres, cylinders and a plane with one kernel cache: the
    first imports trimesh and keeps its shapes, the second loads them (and renders the same)."""
    code = ("import sys, numpy as np, warp_blur as wb\n"
            "from pxr import Usd, UsdGeom\n"
            f"path = {str(tmp_path / 'shapes.usda')!r}\n"
            "stage = Usd.Stage.CreateNew(path)\n"
            "UsdGeom.Sphere.Define(stage, '/S').AddTranslateOp().Set((0.0, 0.0, -6.0))\n"
            "c = UsdGeom.Cylinder.Define(stage, '/C'); c.CreateAxisAttr('X'); c.AddTranslateOp().Set((2.0, 0.0, -8.0))\n"
            "p = UsdGeom.Plane.Define(stage, '/P'); p.CreateAxisAttr('Y'); p.AddTranslateOp().Set((0.0, -1.0, -6.0))\n"
            "stage.Save()\n"
            "r = wb.render(path, method='analytic', resolution=(32, 24))\n"
            f"np.save({str(tmp_path / 'img')!r} + sys.argv[1], r.rgba)\n"
            "print('trimesh' in sys.modules)\n")
    first = subprocess.run([sys.executable, "-c", code, "1"], capture_output=True, text=True, timeout=600)
    second = subprocess.run([sys.executable, "-c", code, "2"], capture_output=True, text=True, timeout=600)
    assert first.returncode == 0 and second.returncode == 0, first.stderr + second.stderr
    assert second.stdout.strip() == "False"
    assert np.array_equal(np.load(tmp_path / "img1.npy"), np.load(tmp_path / "img2.npy"))
