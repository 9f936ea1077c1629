"""core/parallel.py: band launches cover every pixel once whatever the band count, and
run_prepared runs prepared passes in order while the next one is being prepared."""

from __future__ import annotations

import threading

import numpy as np
import pytest
import warp as wp

from warp_blur.core.parallel import FINE_BANDS, launch_pixels, run_prepared


@wp.kernel(enable_backward=False)
def count_pixels(first: int, hits: wp.array(dtype=int)):
    hits[first + wp.tid()] += 1


@pytest.mark.parametrize("bands", [1, 4, FINE_BANDS])
def test_every_pixel_is_launched_once(bands):
    hits = wp.zeros(1000, dtype=int, device="cpu")
    launch_pixels(count_pixels, 1000, lambda first, _n: [first, hits], "cpu", threads=2, bands_per_thread=bands)
    np.testing.assert_array_equal(hits.numpy(), np.ones(1000, np.int32))


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
