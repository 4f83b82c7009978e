"""Optional wall-clock accounting of where a sample's time goes.

The caller that wants the seconds opens a collector; the code that does the work marks its steps::

    with collect_timings() as timings:   # a benchmark, a test
        dataset.sample(0)
    timings["shadow"]                    # seconds, summed over every ``with timed("shadow"):`` block

    with timed("shadow", GL.glFinish):   # the renderer
        ...

:func:`timed` adds its block's seconds to the collector open in the current context (the innermost
:func:`collect_timings` of this thread or asyncio task, held in a ``contextvars.ContextVar``); with none
open it runs the block untouched, at the cost of one ``ContextVar`` read (no clock read, no sync).
So no signature carries a timings argument, and collections never mix: a thread or task starts with
no collector of its own whatever another has open, and a nested collector takes its block's seconds
while the outer one gets none of them.
"""

from __future__ import annotations

import time
from contextlib import contextmanager, nullcontext
from contextvars import ContextVar
from typing import Callable, ContextManager, Iterator

__all__ = ["add_timings", "collect_timings", "collecting", "stopwatch", "timed"]

_UNTIMED = nullcontext()

_COLLECTOR: ContextVar[dict[str, float] | None] = ContextVar("sidar_torch_timings", default=None)
"""The seconds per step of the innermost open :func:`collect_timings`, or None."""


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


def stopwatch(timings: dict[str, float], key: str, sync: Callable[[], object] | None = None) -> ContextManager[None]:
    """A context manager adding the seconds spent in its block to ``timings[key]`` (summed over blocks).

    Args:
        timings: the accumulator (seconds per key).
        key: the step the block's time belongs to.
        sync: called at the end of the block before the clock is read (e.g. ``GL.glFinish``, so that
            work a driver queued lands in this step, not a later one); not called when the block raises.
    """
    return _Stopwatch(timings, key, sync)


def timed(key: str, sync: Callable[[], object] | None = None) -> ContextManager[None]:
    """:func:`stopwatch` into the collector open in this context (:func:`collect_timings`), or a block
    that runs untouched when none is (``sync`` is then not called either)."""
    timings = _COLLECTOR.get()
    return _UNTIMED if timings is None else _Stopwatch(timings, key, sync)


def collecting() -> bool:
    """Whether a collector is open in this context (:func:`collect_timings`): whether :func:`timed` measures."""
    return _COLLECTOR.get() is not None


def add_timings(seconds: dict[str, float]) -> None:
    """Add ``seconds`` (step -> seconds, e.g. collected in another process) to the collector open in this
    context, key by key; nothing when none is open."""
    timings = _COLLECTOR.get()
    if timings is not None:
        for key, value in seconds.items():
            timings[key] = timings.get(key, 0.0) + value


@contextmanager
def collect_timings() -> Iterator[dict[str, float]]:
    """Collect the seconds of every :func:`timed` step run inside the block, in this thread or task:
    yields the dict they are added to (step -> seconds, summed), filled as the block runs.

    Keys are the steps' names: the renderer's (``sidar_torch.render.SceneRenderer.render``), the
    sample's (``sidar_torch.sample.render_arrays``). A nested collector takes the seconds of its own
    block; the outer one resumes after it.
    """
    timings: dict[str, float] = {}
    token = _COLLECTOR.set(timings)
    try:
        yield timings
    finally:
        _COLLECTOR.reset(token)
