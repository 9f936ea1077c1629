"""Benchmark helpers: warm-up, medians of repeats, tables, output folder."""

from __future__ import annotations

import json
import os
import statistics
import time
from typing import Callable

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
OUT = os.path.join(ROOT, "bench", "out")
SCENES = os.path.join(ROOT, "usd_scenes")


def timed_median(fn: Callable[[], object], repeats: int = 3, long_run_s: float = 20.0) -> tuple[float, object]:
    """Median wall time of `repeats` calls after one warm-up call; returns (seconds, last result).

    A warm-up slower than `long_run_s` is timed once more only (long runs are not noisy enough
    to need a median, and repeating them would take the benchmark past its budget). One fn's
    timed_rounds."""
    return timed_rounds([fn], repeats, long_run_s)[0]


def timed_rounds(fns: list[Callable[[], object]], repeats: int = 3, long_run_s: float = 20.0,
                 progress: Callable[[], None] | None = None) -> list[tuple[float, object]]:
    """[(median wall time, last result)] of each of fns: one warm-up call each, then `repeats`
    rounds that call every fn in turn, each round starting one further along. On a shared machine
    whose speed swings from second to second, a burst of load then slows one call of several fns
    instead of every call of one, so the ratios between fns measured in one run hold (timing each
    fn's calls back to back, as timed_median of one fn does, would not). A fn whose warm-up took
    longer than `long_run_s` is timed once more only, in the first round. progress() is called
    after each warm-up and each round."""
    results: list[object] = [None] * len(fns)
    warm = [0.0] * len(fns)
    for i, fn in enumerate(fns):
        t0 = time.perf_counter()
        results[i] = fn()
        warm[i] = time.perf_counter() - t0
        if progress is not None:
            progress()
    times: list[list[float]] = [[] for _ in fns]
    for r in range(repeats):
        for j in range(len(fns)):
            i = (j + r) % len(fns)
            if warm[i] > long_run_s and times[i]:
                continue
            t0 = time.perf_counter()
            results[i] = fns[i]()
            times[i].append(time.perf_counter() - t0)
        if progress is not None:
            progress()
    return [(statistics.median(t) if t else warm[i], results[i]) for i, t in enumerate(times)]


def table(rows: list[dict], columns: list[str]) -> str:
    """Plain-text table of rows (dicts) with the given columns."""
    def fmt(v):
        return f"{v:.4g}" if isinstance(v, float) else str(v)
    widths = [max(len(c), *(len(fmt(r.get(c, ""))) for r in rows)) for c in columns]
    lines = ["  ".join(c.ljust(w) for c, w in zip(columns, widths)),
             "  ".join("-" * w for w in widths)]
    lines += ["  ".join(fmt(r.get(c, "")).ljust(w) for c, w in zip(columns, widths)) for r in rows]
    return "\n".join(lines)


def save(name: str, data) -> str:
    os.makedirs(OUT, exist_ok=True)
    path = os.path.join(OUT, name)
    with open(path, "w") as f:
        json.dump(data, f, indent=2, default=str)
    return path


def pyplot():
    """matplotlib.pyplot on the Agg backend, or None (with a message) when matplotlib is missing:
    a bench still prints and saves its tables without the `bench` extra."""
    try:
        import matplotlib
    except ImportError:
        print("no plot: matplotlib is not installed (pip install -e '.[bench]')")
        return None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


METHODS = ["analytic", "stochastic", "accumulation", "velocity"]


def median_frame_seconds(render, frames: list[float]) -> float:
    """Median seconds of render(frame) over `frames`, after a warm-up at the frame before the first
    (a Renderer's kept state is then what a batch render reaches)."""
    render(frames[0] - 1)
    times = []
    for f in frames:
        t0 = time.perf_counter()
        render(f)
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def a_against_b(seconds: Callable[[str, bool], float], columns: tuple[str, str], desc: str) -> list[dict]:
    """Per method, seconds(method, True) and seconds(method, False) as columns (a, b) and their
    ratio b / a, under a progress bar: one run, so the ratio is what to read."""
    from tqdm import tqdm
    rows = []
    with tqdm(total=2 * len(METHODS), desc=desc, unit="run") as bar:
        for method in METHODS:
            row = {"method": method}
            for flag, column in zip((True, False), columns):
                row[column] = seconds(method, flag)
                bar.update()
            row[f"{columns[1].split()[0]} / {columns[0].split()[0]}"] = row[columns[1]] / row[columns[0]]
            rows.append(row)
    return rows
