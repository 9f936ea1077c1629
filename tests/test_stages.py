"""The checked-in stages are exactly what their stages/ scripts write (deterministic authoring)."""

import glob
import importlib.util
import os

import pytest
from conftest import ROOT, SCENES

SCRIPTS = sorted(glob.glob(os.path.join(ROOT, "stages", "make_*.py")))


@pytest.mark.parametrize("script", SCRIPTS, ids=os.path.basename)
def test_checked_in_stage_matches_script(tmp_path, script):
    name = os.path.basename(script)[len("make_"):-3]
    spec = importlib.util.spec_from_file_location(f"make_{name}", script)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    out = str(tmp_path / f"{name}.usda")
    mod.main(out)
    with open(out) as a, open(os.path.join(SCENES, f"{name}.usda")) as b:
        assert a.read() == b.read()
