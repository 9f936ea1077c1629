"""bench/bench_peers.py without Blender: its sweeps time all four methods, its per-scene summary
gives every curve a time to each target and issue 18's verdicts only on the rivals the issue
names, and with no bpy anywhere it says so and exits cleanly (it is never run in CI)."""

from __future__ import annotations

import math
import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "bench"))
import bench_peers  # noqa: E402


def test_the_sweeps_time_all_four_methods():
    for quick in (False, True):
        assert set(bench_peers.ours_sweeps(quick)) == {"analytic", "stochastic", "accumulation", "velocity"}


def _rows(method: str, points: list[tuple[float, float]], note: str = "") -> list[dict]:
    return [{"method": method, "seconds": t, "rmse": e, "note": note} for t, e in points]


def test_scene_summary_times_every_curve_and_judges_only_the_issue_rivals():
    rows = (_rows("analytic", [(0.1, 0.003), (0.2, 0.0005)])
            + _rows("stochastic", [(0.2, 0.008), (0.4, 0.002), (0.8, 0.0005)])
            + _rows("accumulation", [(0.3, 0.006), (1.2, 0.0015), (4.8, 0.0004)])
            + _rows("velocity", [(0.05, 0.05), (0.1, 0.045)])
            + _rows("cycles", [(1.0, 0.006), (4.0, 0.0012), (16.0, 0.0009)]))
    summary = bench_peers.scene_summary("s", rows)
    assert [e["target_rmse"] for e in summary] == list(bench_peers.TARGETS)
    at_002 = summary[1]
    assert at_002["t_stochastic"] == 0.4
    assert math.isinf(at_002["t_velocity"]) and math.isinf(at_002["x_velocity"])
    assert at_002["x_stochastic"] == at_002["t_stochastic"] / at_002["t_analytic"]
    verdicts = at_002["targets"]
    assert "velocity" not in verdicts
    for rival in ("stochastic", "accumulation", "cycles"):
        assert rival in verdicts
    assert "MISSED" in verdicts   # a lead of about 3.4x over stochastic against the 5x asked


def test_a_cycles_conversion_mismatch_is_left_out_of_the_targets():
    rows = (_rows("analytic", [(0.1, 0.003), (0.2, 0.0005)])
            + _rows("stochastic", [(0.2, 0.008), (0.8, 0.0005)])
            + _rows("cycles", [(1.0, 0.02), (4.0, 0.015)], note="conversion mismatch"))
    for entry in bench_peers.scene_summary("s", rows):
        assert "t_cycles" not in entry and "cycles" not in entry["targets"]


def test_without_bpy_the_bench_says_so_and_returns(monkeypatch, capsys):
    monkeypatch.setattr(bench_peers, "bpy_python", lambda explicit: None)
    monkeypatch.setattr(sys, "argv", ["bench_peers.py"])
    bench_peers.main()
    assert "skipped" in capsys.readouterr().out


def test_a_python_that_is_not_there_counts_as_no_bpy(monkeypatch):
    monkeypatch.delenv("WARP_BLUR_BPY_PYTHON", raising=False)
    assert bench_peers.bpy_python(os.path.join(ROOT, "no", "such", "python")) in (None, sys.executable)
