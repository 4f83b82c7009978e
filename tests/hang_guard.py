"""A hang guard for tests that tells a hang from a slow machine.

A wall-clock guard fails a computation that is only slow: at load 20 on 2 cores a process gets about a
tenth of a core, and a sample that renders in 8 s idle takes 80 s. :func:`no_hang` counts this
process's CPU time instead, which a busy machine stretches in wall time but not in amount, and catches
the two ways a block can hang:

* it **spins** (a Python loop that never ends, native code that computes forever): the process's CPU
  time in the block passes ``cpu_seconds``;
* it **blocks** (a deadlock, a wait on something that never comes): the process uses next to no CPU
  (under :data:`PROGRESS_CPU_SECONDS`) for ``idle_seconds`` of wall time. A progressing process on a
  loaded machine still gets its share of a core every scheduler period (a tenth at load 20 on 2
  cores: 0.1 s of CPU in about 1 s), far more than this.

Meant for computations that run in the calling thread of this process (rendering, sampling). A child
process's spin is bounded by :func:`cap_cpu` (the kernel counts its CPU time), with
:data:`CHILD_WALL_SECONDS` of wall time as the backstop for a child that blocks.
"""

from __future__ import annotations

import contextlib
import faulthandler
import signal
import threading
import resource
import time
from typing import Callable, Iterator

IDLE_SECONDS = 30.0
"""Default wall time with next to no CPU used after which a block counts as blocked, seconds."""

PROGRESS_CPU_SECONDS = 0.1
"""CPU time the process must use within ``idle_seconds`` of wall time to count as progressing, seconds."""

POLL_SECONDS = 0.25
"""How often the watchdog thread reads the process's CPU time, seconds of wall time."""

BACKSTOP_SLOWDOWN = 20
"""Wall time per second of ``cpu_seconds`` after which the process ends with a traceback
(``faulthandler``) if the ``TimeoutError`` could not be raised (native code that never returns to
the interpreter): a slowdown of 20, load 40 on 2 cores, still finishes the block first."""


CHILD_WALL_SECONDS = 600
"""Wall-time limit (``subprocess.run(timeout=)``) for a child whose CPU time :func:`cap_cpu` bounds:
importing ``sidar_torch`` alone takes 2-4 s of CPU time, 20-40 s of wall time at load 20 on 2 cores."""


def cap_cpu(seconds: int) -> Callable[[], None]:
    """A ``preexec_fn`` for ``subprocess`` that ends the child once it has used ``seconds`` of its own
    CPU time (``RLIMIT_CPU``: ``SIGXCPU``, exit status -24), however slowly the machine runs it."""
    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_CPU, (seconds, seconds + 1))
    return limit


class _Watchdog(threading.Thread):
    """Reads the process's CPU time every :data:`POLL_SECONDS` and, once, sends ``SIGALRM`` to the
    guarded thread with the reason in :attr:`reason` when the block spins or blocks."""

    def __init__(self, cpu_seconds: float, idle_seconds: float, target: int):
        super().__init__(name="no_hang watchdog", daemon=True)
        self.cpu_seconds, self.idle_seconds, self.target = cpu_seconds, idle_seconds, target
        self.reason: str | None = None
        self.done = False
        self._lock = threading.Lock()
        self._finished = threading.Event()

    def run(self) -> None:
        start = mark_cpu = time.process_time()
        mark_wall = time.monotonic()
        while not self._finished.wait(POLL_SECONDS):
            cpu, wall = time.process_time(), time.monotonic()
            if cpu - start > self.cpu_seconds:
                reason = f"spinning: used more than {self.cpu_seconds:g} s of CPU time"
            elif cpu - mark_cpu >= PROGRESS_CPU_SECONDS:
                mark_cpu, mark_wall = cpu, wall
                continue
            elif wall - mark_wall > self.idle_seconds:
                reason = (f"blocked: used under {PROGRESS_CPU_SECONDS:g} s of CPU time in "
                          f"{self.idle_seconds:g} s of wall time")
            else:
                continue
            with self._lock:
                if not self.done:
                    self.reason = f"still running: {reason} ({cpu - start:.1f} s of CPU in the block)"
                    signal.pthread_kill(self.target, signal.SIGALRM)
            return

    def finish(self) -> None:
        """Send nothing from now on and end the thread."""
        with self._lock:
            self.done = True
        self._finished.set()
        self.join()


@contextlib.contextmanager
def no_hang(cpu_seconds: float, idle_seconds: float = IDLE_SECONDS) -> Iterator[None]:
    """Raise ``TimeoutError`` in the block when it spins or blocks, whatever the machine's load.

    Args:
        cpu_seconds: CPU time this process may use in the block (every thread), seconds.
        idle_seconds: wall time in which the process must use :data:`PROGRESS_CPU_SECONDS` of CPU,
            seconds; a block that does not counts as blocked.

    Raises:
        TimeoutError: in the block, naming which of the two it did (a blocking system call or lock
            wait is interrupted by the signal). If native code does not return to the interpreter
            within ``BACKSTOP_SLOWDOWN * cpu_seconds + idle_seconds`` of wall time, the process ends
            with every thread's traceback rather than block the suite.
        RuntimeError: called outside the main thread (only it receives Python signal handlers).
    """
    if threading.current_thread() is not threading.main_thread():
        raise RuntimeError("no_hang: expected to be entered in the main thread (it raises through SIGALRM)")
    watchdog = _Watchdog(cpu_seconds, idle_seconds, threading.get_ident())

    def expire(signum, frame):
        if not watchdog.done:
            raise TimeoutError(watchdog.reason)

    previous = signal.signal(signal.SIGALRM, expire)
    faulthandler.dump_traceback_later(BACKSTOP_SLOWDOWN * cpu_seconds + idle_seconds, exit=True)
    watchdog.start()
    try:
        yield
    finally:
        try:
            watchdog.finish()
        finally:
            faulthandler.cancel_dump_traceback_later()
            signal.signal(signal.SIGALRM, previous)
