"""Processes that render end with the process they work for: the one "exit when it dies" helper.

Every fan-out of rendering into forked children calls :func:`exit_with_parent` first thing in the
child: the ``SidarAugment`` render pool (:mod:`sidar_torch.data.render_pool`) does, and a DataLoader
``worker_init_fn`` can (``exit_with_parent(parent_pid)`` with the pid read before the fork, or
``os.getppid()`` read at once in the worker). A render child has nothing worth saving when its
parent is gone (its results would go nowhere), so it ends at once, with ``os._exit``/``SIGKILL``,
whatever it is doing: rendering, waiting for a task, or blocked sending a reply no one reads.

Three mechanisms, because each alone has a gap:

* ``prctl(PR_SET_PDEATHSIG, signal)`` (Linux): the kernel sends the child ``signal`` when the parent
  *thread* that forked it ends (and again whenever the thread it was handed to ends, the last time
  when the whole parent dies). Forked by the parent's main thread (``death_signal``), the signal is
  ``SIGKILL``, which ends the child even if it is stopped (``SIGSTOP``). Forked by another thread,
  ``SIGKILL`` would end the child with that thread (a pool started from a short-lived thread would
  lose its workers), so the signal is ``SIGCONT``: harmless to a running child, it wakes a stopped
  one, whose watching thread (next) then sees the parent gone. Without it a stopped child of a
  killed parent stayed stopped for good (state ``T``, parent pid 1): a stopped process runs no
  thread, and ``SIGKILL`` and ``SIGCONT`` are the only signals it acts on.
* a daemon thread that checks ``os.getppid()`` every :data:`POLL_S` seconds and leaves with
  ``os._exit(1)`` when the parent is gone (it is reparented): works on every POSIX system and for
  children forked by any thread; it needs the GIL, which a blocked ``send`` or a GL call releases.
* :func:`release_inherited_descriptors`: a forked child holds a copy of every descriptor of its
  parent, among them the parent's ends of its own pipe (and of its siblings'), so a reply larger
  than the socket buffer blocked forever in ``send`` after the parent died. Released, the parent's
  death closes the last copy of its ends, and a ``send`` fails at once with ``EPIPE``. (The render
  pool calls it; a DataLoader worker cannot, as PyTorch's own pipes are among what it inherited.)

The parent may die between the fork and these calls; :func:`exit_with_parent` checks ``getppid``
after arming the signal, so that window is closed too.

Ray's workers are not children of the process that drives an export (``sidar_torch.io.cluster``): Ray
ends a dead driver's tasks only 2-5 s later, and until then they kept rendering and writing into an
export folder whose lock died with the driver. :func:`exit_with_process` watches such a process by
its :class:`ProcessStamp` (pid and start time, which tell it from a later process given the same
pid) with the same polling thread.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import pickle
import signal
import stat
import sys
import threading
import time
import traceback
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterable

__all__ = ["ENDINGS", "POLL_S", "ProcessStamp", "end_processes", "exit_with_parent", "exit_with_process",
           "open_descriptors", "portable_exception", "process_age", "process_state",
           "release_inherited_descriptors"]

POLL_S = 0.25
"""How often, in seconds, the watching thread checks that the parent is alive."""

_PR_SET_PDEATHSIG = 1  # from <linux/prctl.h>


def _arm_death_signal(sent: signal.Signals) -> bool:
    """Ask Linux to send this process ``sent`` when its parent thread ends; False where unavailable."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        return libc.prctl(_PR_SET_PDEATHSIG, int(sent), 0, 0, 0) == 0
    except (OSError, AttributeError):
        return False


def exit_with_parent(parent_pid: int, *, death_signal: bool = True) -> None:
    """Make this process (a forked child) end within :data:`POLL_S` seconds of its parent's death,
    even if it is stopped (``SIGSTOP``) then.

    Args:
        parent_pid: the pid of the parent, read *before* the fork (or at once after it), so that a
            parent that died in between is noticed.
        death_signal: the fork was made by the parent's main thread: Linux's parent-death signal is
            ``SIGKILL``. Pass False when another thread made it: the signal is then ``SIGCONT``, which
            that thread's end sends harmlessly and which wakes this process, if stopped, when the
            parent dies (see the module docstring).

    Ends the process at once (``os._exit(1)``) if the parent is already gone.
    """
    _arm_death_signal(signal.SIGKILL if death_signal else signal.SIGCONT)
    if os.getppid() != parent_pid:
        os._exit(1)
    _exit_when(lambda: os.getppid() == parent_pid, "sidar-exit-with-parent")


def _exit_when(alive: Callable[[], bool], name: str) -> None:
    """Start a daemon thread that checks ``alive()`` every :data:`POLL_S` seconds and ends this
    process (``os._exit(1)``) once it is false."""

    def watch() -> None:
        while alive():
            time.sleep(POLL_S)
        os._exit(1)

    threading.Thread(target=watch, name=name, daemon=True).start()


@dataclass(frozen=True)
class ProcessStamp:
    """A process on this machine: its pid and its start time (``None`` without ``/proc``), which
    tell it from a later process given the same pid. Picklable (sent to Ray tasks)."""

    pid: int
    started: str | None

    @classmethod
    def this_process(cls) -> ProcessStamp:
        return cls(os.getpid(), _start_time(os.getpid()))

    def alive(self) -> bool:
        """Whether the process still runs (a zombie does not); false on a machine without ``/proc``."""
        return _start_time(self.pid) == self.started


def _stat_fields(pid: int) -> list[bytes] | None:
    """Fields 3 on of ``/proc/<pid>/stat`` (``[0]`` the state letter, ``[19]`` field 22, the start
    time in clock ticks after boot), or ``None`` if there is no such process or no ``/proc``."""
    try:
        stat_line = Path(f"/proc/{pid}/stat").read_bytes()
    except OSError:
        return None
    return stat_line.rpartition(b")")[2].split()  # after the name, which may hold spaces: state, ppid, ...


def _start_time(pid: int) -> str | None:
    """When process ``pid`` started (field 22 of ``/proc/<pid>/stat``, clock ticks after boot), or
    ``None`` if there is no such live process (a zombie is dead) or no ``/proc``."""
    fields = _stat_fields(pid)
    return None if fields is None or fields[0] in (b"Z", b"X") else fields[19].decode()


def process_age(pid: int) -> float | None:
    """Seconds since process ``pid`` started (10 ms steps, ``/proc``); ``None`` if there is no such
    process or no ``/proc``."""
    fields = _stat_fields(pid)
    if fields is None or not hasattr(time, "CLOCK_BOOTTIME"):
        return None
    return max(time.clock_gettime(time.CLOCK_BOOTTIME) - int(fields[19]) / os.sysconf("SC_CLK_TCK"), 0.0)


_STATES = {b"R": "running", b"S": "sleeping", b"D": "waiting for a device", b"T": "stopped (SIGSTOP or Ctrl-Z)",
           b"t": "stopped by a debugger", b"Z": "dead (a zombie, not yet reaped)", b"X": "dead", b"I": "idle"}
"""What the state letter of ``/proc/<pid>/stat`` means (``man 5 proc``)."""


def process_state(pid: int) -> str:
    """Process ``pid``'s state in words, for error messages: ``"stopped (SIGSTOP or Ctrl-Z)"``,
    ``"running"``, ``"gone"`` (no such process), ``"unknown"`` (no ``/proc``)..."""
    fields = _stat_fields(pid)
    if fields is None:
        return "gone" if Path("/proc/self/stat").exists() else "unknown"
    return _STATES.get(fields[0], f"state {fields[0].decode()!r}")


_watched: set[ProcessStamp] = set()
"""The processes this process watches (:func:`exit_with_process`)."""


def exit_with_process(process: ProcessStamp) -> None:
    """End this process within :data:`POLL_S` seconds of ``process``'s death (once per process
    watched, however often called).

    The watch starts only where ``process`` is seen alive, i.e. on its machine (the same pid and
    start time): elsewhere (another node of a Ray cluster) the caller's own clean-up must end this
    process. A Ray task's folder or shard is written atomically, so leaving at once loses nothing.
    """
    if process in _watched or process.started is None or not process.alive():
        return
    _watched.add(process)
    _exit_when(process.alive, "sidar-exit-with-process")


def open_descriptors() -> set[int]:
    """The descriptors open in this process (from ``/proc/self/fd`` or ``/dev/fd``; empty if neither)."""
    for folder in ("/proc/self/fd", "/dev/fd"):
        try:
            names = os.listdir(folder)
        except OSError:
            continue
        return {fd for fd in map(int, names) if _is_open(fd)}  # listing used a descriptor, closed by now
    return set()


def _is_open(fd: int) -> bool:
    try:
        os.fstat(fd)
    except OSError:
        return False
    return True


def release_inherited_descriptors(inherited: Iterable[int]) -> None:
    """Let go of the descriptors ``inherited`` (except stdin, stdout and stderr) in a forked child.

    ``inherited`` is what the parent had open just before the fork (:func:`open_descriptors`, read
    in the parent), less what the child keeps (its own pipe end). Descriptors made by the fork
    machinery itself (``multiprocessing``'s pipes that tell the parent the child ended) are newer,
    so they are not in it and stay open.

    Sockets, pipes, regular files and folders are released; devices and anonymous kernel objects
    (a GPU's ``/dev/dri`` node, its fences) are kept: the GL driver state the child inherited with
    its parent's EGL display is bound to them, and they hold no pipe end.

    Each one is pointed at ``/dev/null`` (``dup2``) rather than closed: the parent's Python objects
    copied into the child (its connections, files, sockets) still hold those numbers, and one of
    them closing "its" number later must not close a file this child opened since. The files,
    pipes and sockets themselves are released, so the parent's ends of every pipe close for good
    when the parent dies.
    """
    null = os.open(os.devnull, os.O_RDWR)
    try:
        for fd in sorted(set(inherited) - {0, 1, 2, null}):
            if _releasable(fd):
                os.dup2(null, fd, inheritable=False)
    finally:
        os.close(null)


def _releasable(fd: int) -> bool:
    """Whether ``fd`` is open and a socket, pipe, regular file or folder."""
    try:
        mode = os.fstat(fd).st_mode
    except OSError:
        return False
    return any(kind(mode) for kind in (stat.S_ISSOCK, stat.S_ISFIFO, stat.S_ISREG, stat.S_ISDIR))


ENDINGS = (((signal.SIGCONT,), 2.0), ((signal.SIGTERM, signal.SIGCONT), 1.0), ((signal.SIGKILL,), 1.0))
"""How :func:`end_processes` ends children whose pipes or sockets their parent closed: the signals of each
step and the seconds it waits after it. ``SIGCONT`` first lets a stopped child see its closed pipe and
leave, and makes it act on a ``SIGTERM`` (a stopped process acts only on ``SIGKILL``)."""


def end_processes(processes: Iterable) -> None:
    """End ``processes`` (``multiprocessing.Process`` children whose pipes the caller closed): wait a
    little for them to leave, then terminate stragglers and kill those that do not end, each step with
    one wait shared by all of them (:data:`ENDINGS`)."""
    processes = list(processes)
    for signals, grace in ENDINGS:
        deadline = time.monotonic() + grace
        for process in processes:
            for sent in signals if process.is_alive() else ():
                with contextlib.suppress(ProcessLookupError):
                    os.kill(process.pid, sent)
        for process in processes:
            process.join(max(deadline - time.monotonic(), 0.0))


def portable_exception(exc: BaseException, where: str) -> BaseException:
    """``exc`` with its traceback as a note saying it was raised in ``where`` (``"the render process (pid
    12)"``), or a ``RuntimeError`` with its text if it does not survive pickling: what a child sends back
    for its parent to raise."""
    text = "".join(traceback.format_exception(exc))
    try:
        copy = pickle.loads(pickle.dumps(exc))
    except Exception:
        copy = RuntimeError(f"{type(exc).__name__}: {exc}")
    copy.add_note(f"raised in {where}:\n{text}")
    return copy
