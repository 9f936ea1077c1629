"""Run pixel kernels over row bands from a thread pool: one CPU launch uses one core, and Warp
releases the GIL during a launch, so bands launched from several threads use every core.
Each pixel is computed by exactly one thread, so results do not depend on the thread count."""

from __future__ import annotations

import os
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from typing import Callable, Generic, Iterable, TypeVar

import warp as wp

from . import log, progress

_pools: dict[tuple[str, int], ThreadPoolExecutor] = {}
_pools_lock = threading.Lock()
#: the pool family of the current thread: a Background job's launches get pools of their own
_family = threading.local()
#: the current thread's cap on launch_pixels' threads (run_prepared sets it while its helper's
#: preparation, not the kernels, holds the passes back)
_launch_cap = threading.local()
#: set in the pools' own threads and in run_prepared's helper: bands launched there run one after
#: another in that thread (queued on the pool, a pool thread's bands could wait for ever behind the
#: jobs waiting on them, and the helper's would wait behind the pass it is meant to overlap)
_serial_thread = threading.local()
T = TypeVar("T")

#: bands per thread for pixel kernels whose cost varies strongly across the image (every pixel
#: shaded at many instants or samples): with 4 bands per thread the slowest band left a core idle
#: for 12-17% of a stochastic or accumulation frame on 2 cores, with 16 for 6-8%
FINE_BANDS = 16
#: accumulation's sharp passes over FINE_BANDS: guided bands may start this many even bands wide
#: (a quarter of the image on 2 threads), where stochastic's stay at 2 (guided_bounds)
SHARP_WIDEST = 8


def default_threads() -> int:
    return max(1, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1))


def _mark_serial_thread() -> None:
    _serial_thread.inside = True


def launches_serially() -> bool:
    """True in a thread of the band and job pools or in run_prepared's helper: launch_pixels,
    launch_row_bands and map_threads called there run in that thread, one band after another."""
    return getattr(_serial_thread, "inside", False)


def _pool(n: int) -> ThreadPoolExecutor:
    key = (getattr(_family, "name", ""), n)
    with _pools_lock:
        if key not in _pools:
            _pools[key] = ThreadPoolExecutor(max_workers=n, thread_name_prefix=f"warp_blur{key[0]}",
                                             initializer=_mark_serial_thread)
        return _pools[key]


class Background(Generic[T]):
    """fn() run on a helper thread from now on, its result (or exception) given by result().
    Its launches and map_threads jobs use pools of their own, so they run beside the caller's
    bands instead of queueing behind them: work with idle gaps (host set-up between short
    launches) fills the cores the caller's passes leave idle, and the other way round."""

    def __init__(self, fn: Callable[[], T], name: str) -> None:
        self._value: T | None = None
        self._error: BaseException | None = None

        def run() -> None:
            _family.name = "_" + name
            try:
                self._value = fn()
            except BaseException as error:   # re-raised by result(), in the caller's thread
                self._error = error
        # (warnings said there go to the caller's scope: core/log.py)
        self._thread = threading.Thread(target=log.carried(run), name=f"warp_blur_{name}", daemon=True)
        self._thread.start()

    def wait(self) -> None:
        """Wait for fn() to end, whatever it returned or raised."""
        self._thread.join()

    def result(self) -> T:
        """Wait for fn() and return what it returned (raise what it raised)."""
        self._thread.join()
        if self._error is not None:
            raise self._error
        return self._value


def _run_bands(kernel, device: str, threads: int, starts: range, run: Callable[[int], None]) -> None:
    """Compile `kernel` once, then run(start) for each band start from the thread pool."""
    wp.load_module(kernel.module, device=device)
    progress.bands_started(len(starts))

    def run_and_report(start: int) -> None:
        run(start)
        progress.band_done()
    if launches_serially():   # (capped bands, from a pool thread or the helper: one after another)
        for start in starts:
            run_and_report(start)
        return
    list(_pool(threads).map(log.carried(run_and_report), starts))


def map_threads(fn: Callable, items: list, threads: int | None = None) -> list:
    """[fn(x) for x in items], run on the shared thread pool (serially with one thread or one
    item): for jobs that each launch single-core kernels and do host work between them."""
    threads = threads or default_threads()
    if threads == 1 or len(items) <= 1 or launches_serially():
        return [fn(x) for x in items]
    return list(_pool(threads).map(log.carried(fn), items))


def run_prepared(steps: Iterable[Callable[[], None]]) -> None:
    """Call the callables `steps` yields, in order, while a helper thread advances the iterable
    to the next one: the host-side preparation of a pass (NumPy, uploads) overlaps the previous
    pass's kernels instead of leaving the cores idle between them. The iterable is only ever
    advanced by the helper, one step at a time, so whatever state it keeps changes in order.

    When preparing a pass takes longer than running one (twice in a row: short passes over a
    large scene, e.g. accumulation's moving tiles), the passes' kernels leave the helper a core
    (launch_pixels gets one thread fewer) instead of contending with it for both; once a capped
    pass runs over twice as long as a preparation, the kernels get every core back. The helper's
    own launches run in its thread (launches_serially): on the pool they would wait behind the
    pass they are meant to overlap (banding the scene's normals there made `large`'s
    accumulation-64 frame 5.2 -> 6.1 s)."""
    iterator = iter(steps)

    @log.carried   # (the steps' warnings go to the caller's scope)
    def advance():
        _mark_serial_thread()   # (its launches would otherwise queue behind the pass it overlaps)
        t0 = time.perf_counter()
        step = next(iterator, None)
        return step, time.perf_counter() - t0

    threads = default_threads()
    slow_preps = 0
    try:
        with ThreadPoolExecutor(max_workers=1, thread_name_prefix="warp_blur_prepare") as helper:
            pending = helper.submit(advance)
            while True:
                step, _ = pending.result()
                if step is None:
                    return
                pending = helper.submit(advance)
                t0 = time.perf_counter()
                step()
                ran = time.perf_counter() - t0
                if threads <= 1:
                    continue
                # still preparing once the pass has run: the preparation is the bottleneck
                prep = pending.result()[1] if pending.done() else float("inf")
                capped = getattr(_launch_cap, "threads", None) is not None
                if not capped:
                    slow_preps = slow_preps + 1 if prep > ran else 0
                    if slow_preps >= 2:
                        _launch_cap.threads = threads - 1
                elif ran > 2.0 * prep:
                    _launch_cap.threads = None
                    slow_preps = 0
    finally:
        _launch_cap.threads = None


def _band_size(total: int, threads: int, bands_per_thread: int) -> int:
    num_bands = min(total, threads * bands_per_thread)
    return (total + num_bands - 1) // num_bands


#: items below which a cheap per-item kernel (a vertex pass) runs as one launch: bands on the
#: thread pool cost ~0.1 ms each, more than such a pass over a few thousand items
CHEAP_PASS_SERIAL_ITEMS = 32768


def cheap_pass_threads(items: int, threads: int | None) -> int | None:
    """The threads for launch_pixels of a kernel doing little per item: 1 below
    CHEAP_PASS_SERIAL_ITEMS, else `threads`."""
    return 1 if items < CHEAP_PASS_SERIAL_ITEMS else threads


#: bands per thread of a cheap pass (launch_cheap): its items cost alike, so even bands balance,
#: and each band's launch costs ~0.05-0.1 ms (guided bands made 11 of every such pass on 2 cores)
CHEAP_BANDS_PER_THREAD = 2


def launch_cheap(kernel, num_items: int, inputs: Callable[[int, int], list], device: str,
                 threads: int | None = None) -> None:
    """launch_pixels for a kernel doing little and the same per item (a vertex or triangle pass):
    one launch below CHEAP_PASS_SERIAL_ITEMS, else CHEAP_BANDS_PER_THREAD even bands a thread."""
    launch_pixels(kernel, num_items, inputs, device, cheap_pass_threads(num_items, threads),
                  bands_per_thread=CHEAP_BANDS_PER_THREAD, guided=False)


def launch_pixels(kernel, num_pixels: int, inputs: Callable[[int, int], list], device: str,
                  threads: int | None = None, start: int = 0, bands_per_thread: int = 4,
                  max_band: int | None = None, widest: int = 2, guided: bool = True) -> None:
    """Launch `kernel` over pixels [start, start + num_pixels); inputs(first, count) gives a
    band's launch inputs. On CPU the range is cut into bands (guided_bounds: shrinking, for
    balance; none wider than `widest` even bands; or, with guided False, threads ×
    bands_per_thread even ones) launched in parallel; on CUDA it is one launch."""
    if num_pixels <= 0:
        return
    threads = threads or default_threads()
    cap = getattr(_launch_cap, "threads", None)
    if cap is not None:
        threads = min(threads, cap)
    if launches_serially():
        threads = 1
    if (device != "cpu" or threads == 1) and (max_band is None or num_pixels <= max_band):
        wp.launch(kernel, dim=num_pixels, inputs=inputs(start, num_pixels), device=device)
        return
    size = _band_size(num_pixels, threads, bands_per_thread)
    if max_band is not None:
        size = max(1, min(size, max_band))
    cuts = (guided_bounds(num_pixels, threads, size, max_band, widest) if guided
            else list(range(0, num_pixels, size)) + [num_pixels])
    bounds = [start + b for b in cuts]
    ends = dict(zip(bounds[:-1], bounds[1:]))

    def run(first: int) -> None:
        count = ends[first] - first
        wp.launch(kernel, dim=count, inputs=inputs(first, count), device=device)

    _run_bands(kernel, device, threads, bounds[:-1], run)


#: pixels below which a band is not cut further (a band's launch costs ~0.05-0.1 ms of its own)
MIN_BAND = 256


def guided_bounds(n: int, threads: int, size: int, max_band: int | None = None, widest: int = 2) -> list[int]:
    """Band boundaries [0, ..., n], the bands shrinking as the work left does ("guided"
    scheduling): each takes 1/(2·threads) of what is left, at most widest·size (a caller asking
    for fine bands has pixels of very unequal cost: stochastic's first bands of n/4 left a core
    idle on `large`, +5%, where accumulation's sharp passes over the same fine bands ran 3% faster
    from n/4 than from 2·size, session 63) and max_band, down to size // 4 (and MIN_BAND). The
    pool hands them out in order, so
    the last to finish are small: with `size`-long bands alone, the slowest band left a core idle
    at the end of the fill for ~5 ms of deep_overlap's draft (session 63), and every small pass
    paid a launch for each of its `size`-long bands however few its pixels."""
    floor = max(min(MIN_BAND, n), size // 4, 1)
    bounds, at = [0], 0
    while at < n:
        band = max(floor, min(-(-(n - at) // (2 * threads)), widest * size))
        if n - at - band < floor:   # no short band left over at the end
            band = n - at
        if max_band is not None:
            band = min(band, max_band)
        at = min(n, at + band)
        bounds.append(at)
    return bounds


def launch_row_bands(kernel, dim: int, rows: int, inputs: Callable[[int, int], list], device: str,
                     threads: int | None = None, bands_per_thread: int = 2) -> None:
    """Launch `kernel` with `dim` threads once per band of output rows [y0, y1) (inputs(y0, y1)
    gives a band's inputs), the bands in parallel. For kernels that scatter into one output from
    many threads: each launch writes only its own rows, so concurrent launches never touch the
    same element (CPU atomics are not atomic across launches running in parallel)."""
    if dim <= 0 or rows <= 0:
        return
    threads = 1 if launches_serially() else threads or default_threads()
    if device != "cpu" or threads == 1:
        wp.launch(kernel, dim=dim, inputs=inputs(0, rows), device=device)
        return
    size = _band_size(rows, threads, bands_per_thread)

    def run(y0: int) -> None:
        wp.launch(kernel, dim=dim, inputs=inputs(y0, min(y0 + size, rows)), device=device)

    _run_bands(kernel, device, threads, range(0, rows, size), run)


class BandCounter:
    """A count that kernels launched in parallel bands add to without racing: each band gets its
    own one-element array (on the CPU, wp.atomic_add is not atomic across concurrent launches)."""

    def __init__(self, device: str) -> None:
        self.device = device
        self._arrays: list[wp.array] = []

    def band(self) -> wp.array:
        """A fresh (1,) int array for one band's launch."""
        array = wp.zeros(1, dtype=int, device=self.device)
        self._arrays.append(array)
        return array

    def total(self) -> int:
        return sum(int(a.numpy()[0]) for a in self._arrays)
