"""core/parallel.py: band launches cover every pixel once whatever the band count,
run_prepared runs prepared passes in order while the next one is being prepared, and a
Background job runs beside the caller on pools of its own."""

from __future__ import annotations

import threading

import numpy as np
import pytest
import warp as wp

from warp_blur.core import parallel
from warp_blur.core.parallel import (CHEAP_BANDS_PER_THREAD, CHEAP_PASS_SERIAL_ITEMS, FINE_BANDS, MIN_BAND,
                                     SHARP_WIDEST, Background, guided_bounds, launch_cheap, launch_pixels,
                                     map_threads, run_prepared)


@wp.kernel(enable_backward=False)
def count_pixels(first: int, hits: wp.array(dtype=int)):
    hits[first + wp.tid()] += 1


@pytest.mark.parametrize("bands", [1, 4, FINE_BANDS])
def test_every_pixel_is_launched_once(bands):
    hits = wp.zeros(1000, dtype=int, device="cpu")
    launch_pixels(count_pixels, 1000, lambda first, _n: [first, hits], "cpu", threads=2, bands_per_thread=bands)
    np.testing.assert_array_equal(hits.numpy(), np.ones(1000, np.int32))


@pytest.mark.parametrize("n, threads, launches", [
    (CHEAP_PASS_SERIAL_ITEMS - 1, 2, 1), (CHEAP_PASS_SERIAL_ITEMS, 2, 2 * CHEAP_BANDS_PER_THREAD),
    (100_003, 2, 2 * CHEAP_BANDS_PER_THREAD), (100_003, 3, 3 * CHEAP_BANDS_PER_THREAD), (100_003, 1, 1)])
def test_a_cheap_pass_launches_every_item_once_in_few_even_bands(n, threads, launches, monkeypatch):
    """launch_cheap: one launch below CHEAP_PASS_SERIAL_ITEMS (or on one thread), else
    CHEAP_BANDS_PER_THREAD even bands a thread (guided bands made 11 of a 36 k-vertex pass on 2
    cores, each paying a launch), every item once."""
    sizes = []
    real = parallel.wp.launch

    def counting(kernel, dim, **kw):
        if kernel is count_pixels:   # (this test's launches only)
            sizes.append(dim)
        return real(kernel, dim=dim, **kw)
    monkeypatch.setattr(parallel.wp, "launch", counting)
    hits = wp.zeros(n, dtype=int, device="cpu")
    launch_cheap(count_pixels, n, lambda first, _n: [first, hits], "cpu", threads)
    np.testing.assert_array_equal(hits.numpy(), np.ones(n, np.int32))
    assert len(sizes) == launches
    assert max(sizes) - min(sizes) <= max(sizes) // 100 + len(sizes)


@pytest.mark.parametrize("start", [0, 37])
def test_every_pixel_of_a_range_with_a_band_cap_is_launched_once(start):
    hits = wp.zeros(start + 5000, dtype=int, device="cpu")
    launch_pixels(count_pixels, 5000, lambda first, _n: [first, hits], "cpu", threads=2, start=start, max_band=700)
    expected = np.concatenate([np.zeros(start, np.int32), np.ones(5000, np.int32)])
    np.testing.assert_array_equal(hits.numpy(), expected)


@pytest.mark.parametrize("n, threads, bands_per_thread, max_band, widest", [
    (36000, 2, 4, None, 2), (786432, 2, FINE_BANDS, None, 2), (786432, 2, FINE_BANDS, None, SHARP_WIDEST),
    (2432, 2, 4, None, 2), (16, 2, 4, None, 2), (100000, 4, 4, 3000, 2), (300, 2, 16, None, 2)])
def test_guided_bands_shrink_to_a_floor_and_cover_the_range(n, threads, bands_per_thread, max_band, widest):
    """Bands cover [0, n) in order; each is at most `widest` uniform bands (and max_band); they do
    not grow until the floor (a quarter of the uniform band, at least MIN_BAND), and none is left
    shorter than the floor at the end, so a pass's last bands are short but not tiny."""
    size = -(-n // (threads * bands_per_thread))
    if max_band is not None:
        size = min(size, max_band)
    bounds = guided_bounds(n, threads, size, max_band, widest)
    bands = np.diff(bounds)
    floor = max(min(MIN_BAND, n), size // 4, 1)
    if 2 * widest >= bands_per_thread and max_band is None and n > 4 * floor:   # the cap does not bind:
        assert bands[0] == -(-n // (2 * threads))                                 # 1/(2·threads) of all
    elif max_band is None and n > 4 * floor:
        assert bands[0] == widest * size
    widest = max(widest * size, floor)
    assert bounds[0] == 0 and bounds[-1] == n and (bands > 0).all()
    assert (bands[:-1] <= widest).all() and bands[-1] < widest + floor
    if max_band is not None:
        assert (bands <= max_band).all()
    assert (bands[:-1] >= min(floor, max_band or floor)).all()
    assert (np.diff(bands[:-1]) <= 0).all()   # shrinking (the last band takes what is left)
    if n > 4 * floor and max_band is None:
        assert len(bands) < 4 * threads * bands_per_thread
        assert bands[-1] < bands[0]


def test_passes_run_in_order_while_the_next_is_prepared():
    log: list[str] = []
    lock = threading.Lock()
    second_prepared = threading.Event()

    def passes():
        for i in range(3):
            with lock:
                log.append(f"prepare {i}")
            if i == 1:
                second_prepared.set()

            def run(i: int = i) -> None:
                if i == 0:   # the first pass runs while the second is prepared on the helper
                    assert second_prepared.wait(5.0)
                with lock:
                    log.append(f"run {i}")
            yield run

    run_prepared(passes())
    assert [e for e in log if e.startswith("run")] == ["run 0", "run 1", "run 2"]
    assert log.index("prepare 1") < log.index("run 0")
    assert log.index("prepare 2") > log.index("prepare 1")


def test_a_failing_preparation_reaches_the_caller():
    def passes():
        yield lambda: None
        raise ValueError("bad pass")

    with pytest.raises(ValueError, match="bad pass"):
        run_prepared(passes())


def test_a_background_job_runs_beside_the_caller_on_pools_of_its_own():
    """The job's map_threads jobs run while every thread of the caller's pool waits for them (on
    a shared pool they would queue behind the caller's jobs until those time out), on threads
    named for the job, and result() gives what the job returned."""
    busy = threading.Barrier(3)
    release = threading.Event()

    def job() -> list[str]:
        busy.wait(5.0)   # both of the caller's pool threads are taken
        out = map_threads(lambda _x: threading.current_thread().name, [0, 1], threads=2)
        release.set()
        return out

    def caller_job(_x: int) -> bool:
        busy.wait(5.0)
        return release.wait(5.0)

    background = Background(job, "test")
    assert all(map_threads(caller_job, [0, 1], threads=2))
    names = background.result()
    assert len(names) == 2 and all(n.startswith("warp_blur_test") for n in names)


def test_a_background_failure_reaches_the_caller():
    def job() -> None:
        raise ValueError("bad maps")

    with pytest.raises(ValueError, match="bad maps"):
        Background(job, "test").result()


def _cap_seen_by_steps(prep_s: float, run_s: list[float]) -> list:
    """The launch cap each step of run_prepared sees, for steps prepared in prep_s seconds
    each and run for run_s[i] seconds."""
    import time
    from warp_blur.core import parallel
    seen = []

    def steps():
        for ran in run_s:
            time.sleep(prep_s)
            yield lambda ran=ran: (seen.append(getattr(parallel._launch_cap, "threads", None)), time.sleep(ran))
    run_prepared(steps())
    assert getattr(parallel._launch_cap, "threads", None) is None   # never left behind
    return seen


def test_passes_leave_the_preparing_helper_a_core_only_while_it_is_the_bottleneck(monkeypatch):
    from warp_blur.core import parallel
    monkeypatch.setattr(parallel, "default_threads", lambda: 4)
    # preparing (40 ms) outlasts running (~0): from the third pass on, kernels get 3 of 4 threads
    seen = _cap_seen_by_steps(0.04, [0.0] * 6)
    assert seen[:2] == [None, None] and seen[3:] == [3, 3, 3]
    # running (60 ms) outlasts preparing (~0): never capped
    assert _cap_seen_by_steps(0.0, [0.06] * 5) == [None] * 5
    # capped passes that then run over twice as long as a preparation get every thread back
    seen = _cap_seen_by_steps(0.03, [0.0, 0.0, 0.0, 0.1, 0.1, 0.0])
    assert seen[3] == 3 and seen[5] is None


def test_bands_launched_from_inside_a_pool_job_never_wait_on_the_busy_pool():
    """Every pool thread running a map_threads job that itself launches bands (a shadow face's
    vertex pass, say): the inner bands run in the job's own thread instead of queueing behind the
    jobs that wait for them (a deadlock)."""
    both_busy = threading.Barrier(2, timeout=30)
    results: list[np.ndarray] = []

    def job(_item: int) -> np.ndarray:
        both_busy.wait()   # both pool threads hold a job before either launches
        hits = wp.zeros(50000, dtype=int, device="cpu")
        launch_pixels(count_pixels, 50000, lambda first, _n: [first, hits], "cpu", threads=2)
        return hits.numpy()

    runner = threading.Thread(target=lambda: results.extend(map_threads(job, [0, 1], threads=2)), daemon=True)
    runner.start()
    runner.join(timeout=60)
    assert not runner.is_alive(), "the jobs' inner bands waited on the pool the jobs hold"
    assert len(results) == 2 and all((r == 1).all() for r in results)


def test_the_preparing_helper_and_pool_threads_launch_serially_the_caller_does_not():
    """run_prepared's helper launches its own bands in its thread (on the pool they would queue
    behind the pass it overlaps), as the pools' threads do; the thread running the passes does not."""
    from warp_blur.core.parallel import launches_serially
    seen: dict[str, bool] = {}

    def steps():
        seen["helper"] = launches_serially()
        yield lambda: seen.__setitem__("caller", launches_serially())

    run_prepared(steps())
    seen["pool"] = map_threads(lambda _x: launches_serially(), [0, 1], threads=2)[0]
    assert seen == {"helper": True, "caller": False, "pool": True}
