"""Warnings about the stage, each said once per prim and reason, collected for the stats."""

from __future__ import annotations

import logging
import threading

logger = logging.getLogger("warp_blur")
_lock = threading.Lock()
_said: set[str] = set()
_collected: list[str] = []


def warn_once(key: str, message: str) -> None:
    """Log `message` the first time `key` is seen in this process (keys name the prim)."""
    with _lock:
        if key in _said:
            return
        _said.add(key)
        _collected.append(message)
    logger.warning(message)


def take_warnings() -> list[str]:
    """Warnings said since the last call (for result.stats)."""
    with _lock:
        out = list(_collected)
        _collected.clear()
    return out


def reset() -> None:
    """Forget what was said (tests, and a new stage in a long-lived process)."""
    with _lock:
        _said.clear()
        _collected.clear()
