"""Optional wall-clock accounting of where a sample's time goes.

Functions that do timed work take ``timings: dict[str, float] | None``. With a dict, each
``with timed(timings, "shadow"):`` block adds its duration in seconds to ``timings["shadow"]``
(summed over calls); with ``None`` the block runs untouched (one ``None`` check, no clock read).
No state lives outside the dict the caller passes, so concurrent or nested samples never mix.
"""

from __future__ import annotations

import time
from contextlib import nullcontext
from typing import Callable, ContextManager

__all__ = ["timed"]

_UNTIMED = nullcontext()


class _Stopwatch:
    __slots__ = ("timings", "key", "sync", "start")

    def __init__(self, timings: dict[str, float], key: str, sync: Callable[[], object] | None):
        self.timings, self.key, self.sync = timings, key, sync

    def __enter__(self) -> None:
        self.start = time.perf_counter()

    def __exit__(self, exc_type, exc, traceback) -> None:
        if exc_type is None and self.sync is not None:
            self.sync()
        self.timings[self.key] = self.timings.get(self.key, 0.0) + time.perf_counter() - self.start


def timed(timings: dict[str, float] | None, key: str,
          sync: Callable[[], object] | None = None) -> ContextManager[None]:
    """A context manager adding the seconds spent in its block to ``timings[key]``.

    Args:
        timings: the accumulator (seconds per key), or ``None`` to time nothing.
        key: the step the block's time belongs to.
        sync: called at the end of the block before the clock is read, only when timing (e.g.
            ``GL.glFinish``, so that work a driver queued lands in this step, not a later one).
    """
    return _UNTIMED if timings is None else _Stopwatch(timings, key, sync)
