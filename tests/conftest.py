"""Shared fixtures: the stage-authoring helpers, the acceptance folder, small scenes in tmp dirs."""

from __future__ import annotations

import os
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "stages"))
ACCEPTANCE = os.path.join(os.path.dirname(ROOT), "shared", "acceptance")
SCENES = os.path.join(ROOT, "usd_scenes")


@pytest.fixture(autouse=True)
def _warnings_start_empty():
    """A test's renders report only what they said: warnings an earlier test's render said and
    never collected (it raised, or a Renderer was made and not rendered) are dropped first, so a
    test asserting a frame's warnings does not depend on what ran before it in its worker."""
    from warp_blur.core import log
    log.take_warnings()
    yield


@pytest.fixture
def scene_path(tmp_path):
    """A function giving a fresh .usda path in the test's tmp dir."""
    counter = iter(range(1000))
    return lambda name="scene": str(tmp_path / f"{name}_{next(counter)}.usda")


def bin_in_entry_order(monkeypatch) -> None:
    """From now on (in this test) the frame's tile lists run in entry order, without entry_near:
    every walk for the nearest hit goes to the end of its list (the reference the nearest-first
    walks are compared with)."""
    from warp_blur.methods.frame import FrameContext
    original_bin = FrameContext.bin_groups

    def entry_order(self, positions, entry_tri, entry_k0, entry_k1, groups, nearest_first=False, counted=True):
        return original_bin(self, positions, entry_tri, entry_k0, entry_k1, groups, False, counted)
    monkeypatch.setattr(FrameContext, "bin_groups", entry_order)
