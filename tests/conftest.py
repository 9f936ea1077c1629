"""Shared fixtures: the stage-authoring helpers, the acceptance folder, small scenes in tmp dirs."""

from __future__ import annotations

import os
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "stages"))
ACCEPTANCE = os.path.join(os.path.dirname(ROOT), "shared", "acceptance")
SCENES = os.path.join(ROOT, "usd_scenes")


@pytest.fixture
def scene_path(tmp_path):
    """A function giving a fresh .usda path in the test's tmp dir."""
    counter = iter(range(1000))
    return lambda name="scene": str(tmp_path / f"{name}_{next(counter)}.usda")
