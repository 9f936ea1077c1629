"""USD's and Warp's own diagnostics, printed by their C++ cores straight to file descriptor 2,
kept off the user's terminal unless asked for (`--verbose`): one bad input stays one line.

While `captured()` is active, fd 2 is a pipe read by a thread; Python's `sys.stderr` (our log
lines, tracebacks, progress bars) writes to the real stderr as before. Lines on the pipe that are
ours (`warp-blur: ...`, from worker processes that inherited fd 2) are passed through; the rest
are passed through with `verbose`, else kept (`held()`) and dropped.
"""

from __future__ import annotations

import contextlib
import io
import os
import sys
import threading
from typing import Iterator

_OUR_PREFIX = b"warp-blur"


class _Capture:
    def __init__(self, real_fd: int, verbose: bool) -> None:
        self.real_fd = real_fd
        self.verbose = verbose
        self.held: list[str] = []

    def pump(self, read_fd: int) -> None:
        """Read the pipe until every writer has closed it, routing line by line."""
        with os.fdopen(read_fd, "rb", buffering=0) as pipe:
            buf = b""
            while True:
                chunk = pipe.read(65536)
                if not chunk:
                    break
                buf += chunk
                *lines, buf = buf.split(b"\n")
                for line in lines:
                    self.route(line + b"\n")
            if buf:
                self.route(buf + b"\n")

    def route(self, line: bytes) -> None:
        if self.verbose or line.startswith(_OUR_PREFIX):
            os.write(self.real_fd, line)
        elif line.strip():
            self.held.append(line.decode("utf-8", "replace").rstrip())


@contextlib.contextmanager
def captured(verbose: bool = False) -> Iterator[_Capture | None]:
    """Route native writes to fd 2 through a filter for the duration of the block. Does nothing
    (yields None) when sys.stderr is not fd 2 (tests capturing it, an embedding application)."""
    try:
        stderr_is_fd2 = sys.stderr.fileno() == 2
    except (AttributeError, OSError, ValueError, io.UnsupportedOperation):
        stderr_is_fd2 = False
    if not stderr_is_fd2:
        yield None
        return
    sys.stderr.flush()
    real_fd = os.dup(2)
    read_fd, write_fd = os.pipe()
    capture = _Capture(real_fd, verbose)
    thread = threading.Thread(target=capture.pump, args=(read_fd,), name="native-stderr", daemon=True)
    thread.start()
    saved_stderr = sys.stderr
    sys.stderr = io.TextIOWrapper(os.fdopen(os.dup(real_fd), "wb", buffering=0), encoding="utf-8",
                                  errors="replace", line_buffering=True, write_through=True)
    os.dup2(write_fd, 2)
    os.close(write_fd)
    try:
        yield capture
    finally:
        sys.stderr.flush()
        os.dup2(real_fd, 2)          # the pipe's last writer in this process is gone
        thread.join(timeout=5.0)     # workers that inherited the pipe have ended by now
        sys.stderr.close()
        sys.stderr = saved_stderr
        os.close(real_fd)
