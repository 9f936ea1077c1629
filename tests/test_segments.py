"""The motion planner (methods/analytic/segments.py): where its bisection checks a prim's path
against the chords of a level, and what that decides."""

import math

import numpy as np
from scenes import emissive_quad_stage

import warp_blur as wb
import warp_blur.methods.analytic.segments as segments
from warp_blur.output.metrics import rmse

RES = (64, 48)


def _swing_stage(path: str, periods: float, amplitude: float = 1.5) -> str:
    """An emissive quad swinging along x, x = amplitude·sin(2π·periods·u) over the shutter u of
    frame 1 (USD times 0.5..1.5; 129 time samples, so USD's linear interpolation follows the sine)."""
    times = [0.5 + i / 128 for i in range(129)]
    samples = {t: (amplitude * math.sin(2 * math.pi * periods * (t - 0.5)), 0.0, 0.0) for t in times}
    return emissive_quad_stage(path, translate_samples=samples, half=1.0)


def test_a_swing_back_on_its_chord_at_mid_shutter_is_seen_at_the_quarter_points(scene_path, monkeypatch):
    """A quad swinging right and back left through one period is where it started at open,
    mid-shutter and close: a level of one segment checked at its midpoint alone takes it as
    moving in a straight line that goes nowhere and renders it sharp. One and two segments are
    checked at their quarter points, which see the swing: it gets its segments, and analytic
    matches accumulation at 1024 instants (against a sharp quad when only midpoints are checked)."""
    path = _swing_stage(scene_path(), periods=1.0)
    ref = wb.render(path, frame=1, resolution=RES, samples=1024, aovs=(), shadows="off")
    out = wb.render(path, frame=1, resolution=RES, method="analytic", aovs=())
    assert out.stats["motion_segments"]["/World/Quad"] >= 8
    assert rmse(out.rgba, ref.rgba) <= 2e-3
    monkeypatch.setattr(segments, "QUARTER_CHECKED_SEGMENTS", 0)   # midpoints at every level
    fooled = wb.render(path, frame=1, resolution=RES, method="analytic", aovs=())
    assert fooled.stats["motion_segments"]["/World/Quad"] == 1
    assert rmse(fooled.rgba, ref.rgba) > 10 * rmse(out.rgba, ref.rgba)


def test_levels_above_two_segments_are_checked_at_their_midpoints(scene_path, monkeypatch):
    """A quad turning half a turn about the view axis needs many segments. Checked at their
    midpoints (where a chord is farthest from an arc) above two segments, they come out as the
    quarter points at every level choose them, from about half the snapshots, and the image is
    the same bit for bit."""
    path = emissive_quad_stage(scene_path(), half=1.5, rotate_axis="Z", rotate_samples={0.5: 0, 1.5: 180})
    kw = dict(frame=1, resolution=RES, method="analytic", aovs=())
    mid = wb.render(path, **kw)
    monkeypatch.setattr(segments, "QUARTER_CHECKED_SEGMENTS", 1 << 20)   # quarter points at every level
    quarter = wb.render(path, **kw)
    assert mid.stats["motion_segments"] == quarter.stats["motion_segments"]
    assert mid.stats["motion_segments"]["/World/Quad"] >= 8
    assert mid.stats["motion_snapshots"] <= 0.6 * quarter.stats["motion_snapshots"]
    assert mid.stats["motion_segment_error_px"] == quarter.stats["motion_segment_error_px"]
    np.testing.assert_array_equal(mid.rgba, quarter.rgba)


def test_checks_per_segment():
    """Quarter points (4 parts) up to QUARTER_CHECKED_SEGMENTS segments, midpoints (2) above."""
    assert [segments.checks_per_segment(k) for k in (1, 2, 4, 8, 64)] == [4, 4, 2, 2, 2]
