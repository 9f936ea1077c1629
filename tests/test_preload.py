"""Kernel modules built before a method's first frame (core/preload.py): each method's list
(methods.KERNEL_MODULES) is exactly the set of modules its frames load by themselves on shipped
stages and a textured real asset, so preloading builds nothing a frame would not, and leaves
nothing for a frame to build."""

import json
import os
import subprocess
import sys

import pytest
from conftest import SCENES

from warp_blur.methods import KERNEL_MODULES

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CUBE = os.path.join(ROOT, "..", "shared", "real_usd", "test_assets", "USDZ", "AnimatedCube", "AnimatedCube.usdz")

#: renders with preloading off, then lists the package's Warp modules that have been loaded
PROBE = """
import json, os, sys
import warp_blur as wb
import warp_blur.core.preload as preload
from warp._src import context as C
preload.ENABLED = False
method, scenes = sys.argv[1], json.loads(sys.argv[2])
for path, frame in scenes:
    wb.render(path, frame=frame, method=method, resolution=(48, 36), samples=4, shutter=(-0.25, 0.25))
print(json.dumps(sorted(n for n, m in C.user_modules.items() if n.startswith("warp_blur") and m.execs)))
"""


@pytest.mark.parametrize("method", sorted(KERNEL_MODULES))
def test_each_method_lists_the_modules_its_frames_load(method):
    scenes = [(os.path.join(SCENES, "demo.usda"), 12), (os.path.join(SCENES, "large.usda"), 2),
              (os.path.join(SCENES, "skinned.usda"), 2)]
    if os.path.exists(CUBE):
        scenes.append((CUBE, 24))
    out = subprocess.run([sys.executable, "-c", PROBE, method, json.dumps(scenes)], capture_output=True, text=True,
                         cwd=ROOT, timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    loaded = set(json.loads(out.stdout.strip().splitlines()[-1]))
    assert loaded == set(KERNEL_MODULES[method])
    assert len(set(KERNEL_MODULES[method])) == len(KERNEL_MODULES[method])


def test_preloading_builds_each_module_once_and_frames_reuse_it(scene_path):
    """After a frame, the modules are loaded once each (a second preload of the same list does
    nothing), and a render still matches one with preloading off."""
    import numpy as np
    import warp_blur as wb
    import warp_blur.core.preload as preload
    from scenes import emissive_quad_stage
    path = emissive_quad_stage(scene_path(), translate_samples={0.5: (-1, 0, 0), 1.5: (1, 0, 0)})
    on = wb.render(path, frame=1, method="analytic", resolution=(32, 24), aovs=())
    assert all((name, "cpu") in preload._loaded for name in KERNEL_MODULES["analytic"])
    preload.ENABLED = False
    try:
        off = wb.render(path, frame=1, method="analytic", resolution=(32, 24), aovs=())
    finally:
        preload.ENABLED = True
    np.testing.assert_array_equal(on.rgba, off.rgba)
