"""Progress inside one frame: the stage being run (FrameContext.timed) and the pixel bands the
thread pool has finished (parallel.py), reported to whoever listens (the CLI's single-frame bar).
Nothing listens by default, and then reporting costs a global read."""

from __future__ import annotations

import threading
from typing import Protocol


class FrameProgress(Protocol):
    def stage(self, name: str) -> None: ...
    def bands_started(self, count: int) -> None: ...
    def band_done(self) -> None: ...


_listener: FrameProgress | None = None
_lock = threading.Lock()


def listen(listener: FrameProgress | None) -> None:
    """Send this process's frame progress to `listener` (None stops it)."""
    global _listener
    _listener = listener


def stage(name: str) -> None:
    if _listener is not None:
        with _lock:
            _listener.stage(name)


def bands_started(count: int) -> None:
    if _listener is not None:
        with _lock:
            _listener.bands_started(count)


def band_done() -> None:
    if _listener is not None:
        with _lock:
            _listener.band_done()


class TqdmFrameProgress:
    """A tqdm bar over the bands of one frame's launches (its total grows as launches start),
    described by the current stage."""

    def __init__(self, bar) -> None:
        self.bar = bar

    def stage(self, name: str) -> None:
        self.bar.set_description_str(name, refresh=False)

    def bands_started(self, count: int) -> None:
        self.bar.total = (self.bar.total or 0) + count
        self.bar.refresh()

    def band_done(self) -> None:
        self.bar.update(1)
