"""The motion planner (methods/analytic/segments.py): where its bisection checks a prim's path
against the chords of a level, and what that decides."""

import math
import re

import numpy as np
import pytest
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


def _entries_unit_by_unit(tri_unit, tri_vertices, seg_of_unit, k_global, vis, vertex_static):
    """plan_entries' reference: the loop over units it replaced (one pass over all triangles per unit)."""
    tri_e, k0_e, k1_e = [], [], []
    tri_ids = np.arange(len(tri_unit), dtype=np.int32)
    for ui, k in enumerate(seg_of_unit):
        tris = tri_ids[tri_unit == ui]
        if k > 0 and vertex_static is not None:
            still = vertex_static[tri_vertices[tris]].all(axis=1)
            fixed = tris[still]
            fixed = fixed[vis[0, fixed]]
            tri_e.append(fixed)
            k0_e.append(np.zeros(len(fixed), np.int32))
            k1_e.append(np.zeros(len(fixed), np.int32))
            tris = tris[~still]
        if k == 0:
            tris = tris[vis[0, tris]]
            tri_e.append(tris)
            k0_e.append(np.zeros(len(tris), np.int32))
            k1_e.append(np.zeros(len(tris), np.int32))
            continue
        step = k_global // k
        for s in range(k):
            t = tris[vis[s * step, tris]]
            tri_e.append(t)
            k0_e.append(np.full(len(t), s * step, np.int32))
            k1_e.append(np.full(len(t), (s + 1) * step, np.int32))
    return tuple(np.concatenate(a).astype(np.int32) for a in (tri_e, k0_e, k1_e))


@pytest.mark.parametrize("seed", range(6))
def test_plan_entries_equal_the_unit_by_unit_loop(seed):
    """Entries of units with 0 to 8 segments, still vertices and visibility switching at knots:
    the same triangles, knots and order as building them unit by unit."""
    from warp_blur.methods.analytic.segments import plan_entries
    rng = np.random.default_rng(seed)
    units = int(rng.integers(1, 30))
    tri_unit = np.sort(rng.integers(0, units, size=int(rng.integers(0, 400)))).astype(np.int32)
    tri_vertices = rng.integers(0, 200, size=(len(tri_unit), 3)).astype(np.int32)
    seg_of_unit = rng.choice([0, 1, 2, 4, 8], size=units)
    k_global = int(max(seg_of_unit.max(), 1))
    vis = rng.random((k_global + 1, len(tri_unit))) < 0.8
    vertex_static = None if seed % 3 == 0 else rng.random(200) < 0.4
    got = plan_entries(tri_unit, tri_vertices, seg_of_unit, k_global, vis, vertex_static)
    want = _entries_unit_by_unit(tri_unit, tri_vertices, seg_of_unit, k_global, vis, vertex_static)
    for g, w in zip(got, want):
        assert g.dtype == np.int32 and np.array_equal(g, w)


def test_a_capped_prim_is_named_with_how_far_its_chords_stray_and_what_was_allowed(scene_path):
    """A quad swinging through 1.3 periods needs more segments than max_segments = 4 allows: it is
    rendered with 4 and listed as capped, and the warning says how far those chords stray from
    USD's path on screen against the tolerance they missed (the first more, the second positive)."""
    path = _swing_stage(scene_path(), periods=1.3)
    out = wb.render(path, frame=1, resolution=RES, method="analytic", aovs=(), max_segments=4)
    assert out.stats["motion_segments"]["/World/Quad"] == 4
    assert out.stats["motion_segments_capped"] == ["/World/Quad"]
    said = [w for w in out.stats["warnings"] if w.startswith("/World/Quad: motion needs more than 4")]
    assert len(said) == 1
    stray, allowed = (float(x) for x in re.search(r"stray up to (\S+) px .* where (\S+) px is allowed", said[0]).groups())
    assert stray > allowed > 0


def test_straddled_chords_bring_a_turning_quad_closer_to_accumulation(scene_path, monkeypatch):
    """A quad turning half a turn in the view plane, at the draft's segment tolerance: with each
    knot moved by 2/3 of its chords' mid-segment deviation (chords.straddle_knots) analytic is at
    least 1.5x closer to accumulation at 1024 instants than with its knots on the arc; a quad
    translating in a straight line renders bit for bit as with the knots left alone."""
    import warp_blur.methods.analytic.chords as chords
    turning = emissive_quad_stage(scene_path(), half=1.5, rotate_axis="Z", rotate_samples={0.5: 0, 1.5: 180})
    ref = wb.render(turning, frame=1, resolution=RES, samples=1024, aovs=(), shadows="off")
    kw = dict(frame=1, resolution=RES, method="analytic", aovs=(), segment_error_px=1.0, segment_time_error=0.004)
    straddled = wb.render(turning, **kw)
    sliding = emissive_quad_stage(scene_path(), translate_samples={0.5: (-1.5, 0.2, 0), 1.5: (1.0, -0.3, 0)})
    line = wb.render(sliding, **kw)
    monkeypatch.setattr(chords, "STRADDLE", 0.0)
    on_arc = wb.render(turning, **kw)
    assert straddled.stats["motion_segments"] == on_arc.stats["motion_segments"]
    assert rmse(straddled.rgba, ref.rgba) * 1.5 <= rmse(on_arc.rgba, ref.rgba)
    np.testing.assert_array_equal(wb.render(sliding, **kw).rgba, line.rgba)


def test_a_prim_whose_chords_barely_stray_is_not_straddled(scene_path, monkeypatch):
    """A quad turning 0.0001 degrees over the shutter has chords within 1e-4 px of its path: the
    planner hands its vertices to straddle_knots only when STRADDLE_MIN_PX allows (the pass over
    `large`'s straight-line rocks moved nothing and cost 2.5 ms), and a quad turning 20 degrees
    is always handed over."""
    seen = []
    real = segments.straddle_knots

    def spy(positions, spans_by_k, mid_positions):
        seen.append(sum(len(v) for v in spans_by_k.values()))
        return real(positions, spans_by_k, mid_positions)
    monkeypatch.setattr(segments, "straddle_knots", spy)
    kw = dict(frame=1, resolution=RES, method="analytic", aovs=())
    creeping = emissive_quad_stage(scene_path(), rotate_axis="Z", rotate_samples={0.5: 0, 1.5: 1e-4})
    turning = emissive_quad_stage(scene_path(), rotate_axis="Z", rotate_samples={0.5: 0, 1.5: 20})
    out = wb.render(creeping, **kw)
    assert 0 < out.stats["motion_segment_error_px"] < segments.STRADDLE_MIN_PX
    wb.render(turning, **kw)
    monkeypatch.setattr(segments, "STRADDLE_MIN_PX", 0.0)
    wb.render(creeping, **kw)
    assert seen == [0, 4, 4]
