"""bench/common.py's timed_rounds: every configuration is timed in rounds that call each in turn
(so a burst of load on a shared machine slows one call of several, not every call of one), long
runs are timed once, and each configuration gets its own median and last result."""

from __future__ import annotations

import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "bench"))
import common  # noqa: E402
from common import timed_rounds  # noqa: E402


class FakeClock:
    """perf_counter for common.time: advanced by the calls themselves."""

    def __init__(self) -> None:
        self.now = 0.0

    def perf_counter(self) -> float:
        return self.now


def test_rounds_call_every_configuration_in_turn_and_take_each_median(monkeypatch):
    clock = FakeClock()
    monkeypatch.setattr(common.time, "perf_counter", clock.perf_counter)
    calls = []
    # a: 1 s a call, b: 2 s, except that the machine is slow (+10 s) during b's second timed call
    plan = {"a": [1.0, 1.0, 1.0, 1.0], "b": [2.0, 2.0, 12.0, 2.0]}

    def job(name):
        def run():
            clock.now += plan[name][sum(c == name for c in calls)]
            calls.append(name)
            return f"{name}{len(calls)}"
        return run
    ticks = []
    out = timed_rounds([job("a"), job("b")], repeats=3, progress=lambda: ticks.append(1))
    # warm-ups, then rounds starting one further along each time
    assert calls == ["a", "b", "a", "b", "b", "a", "a", "b"]
    assert [s for s, _ in out] == [1.0, 2.0]   # the slow call is one of b's three, not its median
    assert [r for _, r in out] == ["a7", "b8"]   # each one's last result
    assert len(ticks) == 2 + 3


def test_a_long_warm_up_is_timed_once(monkeypatch):
    clock = FakeClock()
    monkeypatch.setattr(common.time, "perf_counter", clock.perf_counter)
    counts = {"quick": 0, "long": 0}

    def job(name, seconds):
        def run():
            counts[name] += 1
            clock.now += seconds
        return run
    out = timed_rounds([job("quick", 0.5), job("long", 30.0)], repeats=4, long_run_s=20.0)
    assert counts == {"quick": 5, "long": 2}
    assert [s for s, _ in out] == [0.5, 30.0]


def test_no_rounds_report_the_warm_up():
    out = timed_rounds([lambda: 7], repeats=0)
    assert out[0][1] == 7 and out[0][0] >= 0.0


def test_timed_median_is_one_configurations_rounds(monkeypatch):
    clock = FakeClock()
    monkeypatch.setattr(common.time, "perf_counter", clock.perf_counter)
    steps = iter([1.0, 3.0, 1.0, 2.0])   # warm-up, then three timed calls

    def run():
        clock.now += next(steps)
        return clock.now
    assert common.timed_median(run, repeats=3) == (2.0, 7.0)
