"""Warnings about the stage, each said once per prim and reason within a scope, collected for the
stats.

A scope is one Renderer's (api.py enters it while it opens its stage and renders a frame): two
stages opened in one process each say their own warnings, even about prims of the same path, and
two Renderers rendering in two threads each report only theirs. Code outside every scope (a script
reading a stage with the usd/ readers directly, most unit tests) shares the process's scope. A
frame's work handed to other threads keeps its scope (core/parallel.py runs it through carried()).
"""

from __future__ import annotations

import contextlib
import contextvars
import logging
import threading
from typing import Callable, Iterator, TypeVar

logger = logging.getLogger("warp_blur")
T = TypeVar("T")


class WarningScope:
    """The warnings said in one scope: each key once, messages kept until taken."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._said: set[str] = set()
        self._collected: list[str] = []

    def say(self, key: str, message: str) -> bool:
        """Keep `message` unless `key` was said here before; True when it is new."""
        with self._lock:
            if key in self._said:
                return False
            self._said.add(key)
            self._collected.append(message)
        return True

    def take(self) -> list[str]:
        """The messages said since the last take, in order."""
        with self._lock:
            out = list(self._collected)
            self._collected.clear()
        return out

    def reset(self) -> None:
        """Forget what was said."""
        with self._lock:
            self._said.clear()
            self._collected.clear()


_process = WarningScope()
_current: contextvars.ContextVar[WarningScope | None] = contextvars.ContextVar("warp_blur_warnings", default=None)


def current() -> WarningScope:
    """The scope warnings go to here: the innermost entered in this context, else the process's."""
    return _current.get() or _process


@contextlib.contextmanager
def scope(target: WarningScope) -> Iterator[WarningScope]:
    """Say warnings into `target` within the block (in this thread, and in work carried())."""
    token = _current.set(target)
    try:
        yield target
    finally:
        _current.reset(token)


def carried(fn: Callable[..., T]) -> Callable[..., T]:
    """fn, to be called on another thread, saying its warnings into the caller's scope (each call
    in its own copy of the caller's context, so calls may run at once)."""
    context = contextvars.copy_context()

    def run(*args, **kwargs) -> T:
        return context.copy().run(fn, *args, **kwargs)
    return run


def warn_once(key: str, message: str) -> None:
    """Log `message` the first time `key` is said in the current scope (keys name the prim)."""
    if current().say(key, message):
        logger.warning(message)


def take_warnings() -> list[str]:
    """Warnings said in the current scope since the last call (for result.stats)."""
    return current().take()


def reset() -> None:
    """Forget what the current scope said (tests; outside a Renderer, the process's scope)."""
    current().reset()
