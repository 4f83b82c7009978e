"""A renderer in a process of its own, for a process that may fork: what its own samples render with.

Mesa's on-disk shader cache is what makes a fresh process's first sample cheap (the shader variants
are loaded, not compiled: 0.49 s to a fresh process's first 384x512 ``misaligned`` sample instead of
2.4 s, ``docs/speed.md``, "The first minute"). But the cache writes through a thread, and a child forked after its parent opened
a context with the cache deadlocks at its first new variant (``context._disable_disk_cache_unless_worker``).
A training script's main process forks (DataLoader workers), so it keeps GL out of itself: its
renderer is a :class:`RenderProcess`, a process it forks before opening any context of its own, which
holds the :class:`~.renderer.SceneRenderer` with the cache on and forks nothing. The main process stays
free of GL, so it forks DataLoader workers and render pools safely; each of those opens its own context,
with the cache, whose variants the render process wrote.

``sidar_torch.render.renderer_for`` is the choice: a :class:`RenderProcess` in a process that may fork
(``context.may_fork``), the process's own ``shared_renderer`` elsewhere (a DataLoader worker, a
render-pool worker, the render process itself).

A :class:`RenderProcess` renders what a ``SceneRenderer`` of its settings renders, byte for byte (it is
one, in another process): ``render`` and ``warm_up`` take and return the same things, sent through a
pipe (a 384x512 sequence of 6 views is about 5 MB: 15-20 ms). The steps it times go to the caller's
open ``sidar_torch.timing`` collector; its CPU time is the render process's, not the caller's.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import signal
import threading
import weakref
from typing import Any, Callable

from ..orphans import (end_processes, exit_with_parent, open_descriptors, portable_exception, process_state,
                       release_inherited_descriptors)
from ..timing import add_timings, collect_timings, collecting
from .context import forks_nothing
from .settings import RenderSettings

__all__ = ["RenderProcess"]


class RenderProcess:
    """A :class:`~.renderer.SceneRenderer` for ``settings`` in a forked process of its own.

    Args:
        settings: what the renderer draws (:class:`~.settings.RenderSettings`).
        make_renderer: called in the render process with ``settings`` for its renderer
            (``sidar_torch.render.shared_renderer``).

    Attributes:
        settings, image_size: as the ``SceneRenderer``'s.
        renders: sequences the renderer rendered so far, warm-ups included (as ``SceneRenderer.renders``).
        pid: the render process's.

    The process starts here (a fork: milliseconds; the GL context opens at the first call) and lives
    until :meth:`close` (also at garbage collection and at exit); it exits by itself within a second of
    its parent's death (``sidar_torch.orphans``). It belongs to the process that made it: a forked copy
    (in a DataLoader worker) refuses calls. Calls from several threads take turns. A call interrupted
    while it waits (``KeyboardInterrupt``) ends the render process, whose late reply no later call may
    read; the owner's next call starts a new one (``sidar_torch.render.renderer_for``).
    """

    def __init__(self, settings: RenderSettings, make_renderer: Callable[[RenderSettings], Any]):
        if not isinstance(settings, RenderSettings):
            raise TypeError(f"settings: expected a RenderSettings, got {type(settings).__name__}")
        context = multiprocessing.get_context("fork")
        here, there = context.Pipe()
        inherited = open_descriptors() - {there.fileno()}  # what the render process lets go of
        # Linux's parent-death signal follows the forking thread: SIGKILL only if that is the main thread.
        death_signal = threading.current_thread() is threading.main_thread()
        self.owner = os.getpid()
        self._process = context.Process(target=_serve, name="sidar-render", daemon=True,
                                        args=(there, settings, make_renderer, self.owner, death_signal, inherited))
        self._process.start()
        there.close()
        self.pid = self._process.pid
        self.settings, self.image_size, self.renders = settings, settings.image_size, 0
        self._connection, self._lock = here, threading.Lock()
        self._warmed_up: set = set()
        self._finalizer = weakref.finalize(self, _shut_down, self.owner, here, self._process)

    @property
    def usable(self) -> bool:
        """Whether this process owns the render process and it is open and alive."""
        return self._finalizer.alive and os.getpid() == self.owner and self._process.is_alive()

    def render(self, sequence, painting, **options):
        """``SceneRenderer.render(sequence, painting, **options)`` in the render process: the same
        :class:`~.renderer.RenderedSequence`, and its exceptions (with the render process's traceback
        as a note).

        Raises:
            RuntimeError: the render process died (its pid and exit code named), or this copy of the
                object belongs to another process.
        """
        return self._call("render", sequence, painting, **options)

    def warm_up(self, sequence, key) -> bool:
        """``SceneRenderer.warm_up(sequence, key)`` in the render process; a ``key`` it warmed up already
        returns False here, without a trip through the pipe (each sample's renderer asks)."""
        if key in self._warmed_up:
            return False
        rendered = self._call("warm_up", sequence, key)
        self._warmed_up.add(key)
        return rendered

    def rasteriser(self) -> dict[str, str]:
        """``SceneRenderer.rasteriser()`` of the render process's renderer (what draws its pixels)."""
        return self._call("rasteriser")

    def _call(self, method: str, *args: Any, **kwargs: Any) -> Any:
        if os.getpid() != self.owner:
            raise RuntimeError(f"RenderProcess (pid {self.pid}) belongs to process {self.owner}, not to "
                               f"{os.getpid()}: a forked copy cannot use it (render with renderer_for here)")
        if not self._finalizer.alive:
            raise RuntimeError(f"RenderProcess (pid {self.pid}): called after close()")
        with self._lock:  # one request at a time: replies come in the order of the requests
            try:
                self._connection.send((method, args, kwargs, collecting()))
                status, payload, self.renders, seconds = self._connection.recv()
            except (EOFError, OSError):  # the render process is gone
                self._process.join(1.0)
                how = (f"exit code {self._process.exitcode}" if self._process.exitcode is not None
                       else process_state(self.pid))
                self.close()
                raise RuntimeError(f"the render process (pid {self.pid}) died with {how}") from None
            except BaseException:  # interrupted (Ctrl-C): its reply may still come, which no later call may read
                self.close()
                raise
        add_timings(seconds)
        if status == "error":
            raise payload
        return payload

    def close(self) -> None:
        """End the render process (safe to call twice; does nothing in a process that does not own it)."""
        if os.getpid() == self.owner:
            self._finalizer()
        else:
            self._finalizer.detach()


def _shut_down(owner: int, connection, process) -> None:
    if os.getpid() == owner:
        connection.close()
        end_processes([process])


def _serve(connection, settings: RenderSettings, make_renderer: Callable[[RenderSettings], Any], parent_pid: int,
           death_signal: bool, inherited: set[int]) -> None:
    """The render process: answer ``(method, args, kwargs, timed)`` requests with ``(status, result,
    renders, seconds)`` until the pipe closes or the parent dies (``inherited``: the parent's
    descriptors at the fork, less this end of the pipe)."""
    exit_with_parent(parent_pid, death_signal=death_signal)
    release_inherited_descriptors(inherited)
    # Ctrl-C in a terminal reaches the whole process group: the parent decides (an interrupted call ends
    # this process, see RenderProcess), so this process neither dies of it nor prints a traceback.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    forks_nothing()  # so its context keeps Mesa's disk cache

    renderer = None
    while True:
        try:
            method, args, kwargs, timed = connection.recv()
        except (EOFError, OSError):  # the parent closed the pipe, or died
            return
        seconds: dict[str, float] = {}
        try:
            with collect_timings() if timed else contextlib.nullcontext({}) as seconds:
                renderer = renderer or make_renderer(settings)
                reply = "ok", getattr(renderer, method)(*args, **kwargs)
        except Exception as exc:
            reply = "error", portable_exception(exc, f"the render process (pid {os.getpid()})")
        try:
            connection.send((*reply, renderer.renders if renderer else 0, seconds))
        except OSError:  # the parent closed the pipe (it was interrupted) or died
            return
