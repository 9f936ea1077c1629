"""bench/bench_tradeoff.py's own arithmetic (the bench itself takes minutes and is never run in CI):
the range of each method's error estimate over its measured error."""

from __future__ import annotations

import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "bench"))
import bench_tradeoff  # noqa: E402


def test_estimate_ranges_span_each_methods_ratios_and_skip_rows_without_one():
    rows = [{"method": "analytic", "estimate_ratio": 1.9}, {"method": "analytic", "estimate_ratio": 0.8},
            {"method": "stochastic", "estimate_ratio": 1.3}, {"method": "velocity", "estimate_ratio": ""},
            {"method": "accumulation", "estimate_ratio": 2.5}, {"method": "accumulation", "estimate_ratio": 3.4}]
    assert bench_tradeoff.estimate_ranges(rows) == {"analytic": (0.8, 1.9), "stochastic": (1.3, 1.3),
                                                    "accumulation": (2.5, 3.4)}
