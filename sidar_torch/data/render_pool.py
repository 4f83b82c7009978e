"""Rendering one :class:`sidar_torch.SidarAugment` image, in this process or in a pool of render processes.

A *task* is everything image ``b`` of a call needs: its position, the entropy of its generator
(``numpy.random.default_rng(entropy)`` draws the scene, then the view effects) and its pixels,
``(3, h, w)`` uint8. :func:`render_tasks` turns tasks into :class:`~sidar_torch.sample.SampleArrays`
with the renderer it is handed; it is the only rendering path, whichever process runs it: all of a
batch without a pool (with ``SidarAugment``'s renderer), one task at a time in a pool worker (with the
worker's). It fits and bounds the homographies of the tasks it is given together (one Kornia call, one
NumPy call per step of the error bounds: ``sample.batch_homographies``), which gives each sequence the
values it gets alone, so neither the pixels nor the geometry depend on the pool.

:class:`RenderPool` keeps ``n`` forked processes, each with its own renderer (its copy of the
parent's, or one created and warmed up when the pool starts, ``sidar_torch.sample.warm_up``; then reused),
fed one task at a time through its own socket pair: a process that finishes takes the next task, and
results are put back in batch order.

Bounded waits. The parent never blocks on a worker: each message (an 8-byte length, then a pickle)
goes out and comes in piece by piece on a non-blocking socket (:class:`_Outgoing`,
:class:`_Incoming`), between waits (``selectors.DefaultSelector``: epoll or poll, which take any
descriptor number, where ``select`` fails for one of 1024 or more) that end at the call's deadline
or after :data:`LONGEST_WAIT_S`, whichever comes first, so any finite limit works. A worker
stopped (``SIGSTOP``) or hung while the parent sends it a task larger than the socket buffer, while it
renders, or in the middle of its reply is thus caught by the same ``timeout``, and named with its pid
and state. A new pool's workers warm up (``sidar_torch.sample.warm_up``) before the pool takes tasks, under
their own limit, so a call's ``timeout`` counts no shader compilation.

A worker ends with its parent, whatever it is doing (rendering, waiting, blocked sending a reply
no one reads, or stopped, from whichever thread the pool was started): right after the fork it
calls :func:`sidar_torch.orphans.exit_with_parent` and lets
go of every descriptor it inherited but its own socket end (the parent's ends of every socket pair,
its own included, and any file of the parent's), see :mod:`sidar_torch.orphans`.

Processes are forked (``fork`` start method): a worker starts in milliseconds, where ``spawn`` or
``forkserver`` pay about 2 s of imports each. This is safe after the parent rendered because
``sidar_torch.render`` sets ``LP_NUM_THREADS=0`` (llvmpipe keeps no threads that a child would
miss) and disables Mesa's on-disk shader cache in the parent; a child takes over its copy of the
parent's renderer, with every shader variant the parent compiled (see
:func:`sidar_torch.render.shared_renderer`).
"""

from __future__ import annotations

import dataclasses
import math
import multiprocessing
import os
import pickle
import selectors
import socket
import struct
import threading
import time
import weakref
from typing import TYPE_CHECKING, Any, Callable, Sequence

import numpy as np
import torch

from ..config import MAX_WORKERS, SidarConfig, as_int
from ..orphans import (end_processes, exit_with_parent, open_descriptors, portable_exception, process_state,
                       release_inherited_descriptors)
from ..render import RenderSettings, preload, shared_renderer
from ..render.context import forks_nothing
from ..sample import SampleArrays, batch_homographies, render_arrays
from ..scene import sample_sequence
from ..paintings import TensorPaintings
from ..sample.warm_up import warm_up_renderer

if TYPE_CHECKING:  # the renderer's module imports pyrender: loaded at the first render
    from ..render import SceneRenderer

__all__ = ["LONGEST_WAIT_S", "RenderPool", "RenderTask", "render_tasks"]

LONGEST_WAIT_S = 3600.0
"""The longest one wait for the workers' sockets lasts, seconds; a longer ``timeout`` or
``warm_up_timeout`` is waited out in several. The OS's waits take at most about 24 days (poll's
milliseconds in a C ``int``; ``select`` failed with an ``OverflowError`` from 1e10 s), so without
this a limit such as ``1e300`` (no limit, in practice) raised instead of waiting."""

RenderTask = tuple[int, Sequence[int], np.ndarray]
"""``(position, entropy, image)``: image ``position`` of the batch, the entropy of its generator
(a list of non-negative integers) and its pixels ``(3, h, w)`` uint8."""


def render_tasks(renderer: SceneRenderer, config: SidarConfig, crop: str,
                 tasks: Sequence[RenderTask]) -> list[SampleArrays]:
    """Draw the scene of each task, fit all their homographies in one call, and render each scene
    with its task's image fitted to ``config.image_size``, with ``renderer`` (made for ``config``)."""
    rngs = [np.random.default_rng(list(entropy)) for _, entropy, _ in tasks]
    sequences = [sample_sequence(config, rng) for rng in rngs]
    arrays = []
    for (position, _, image), rng, sequence, homographies in zip(tasks, rngs, sequences, batch_homographies(sequences)):
        painting = TensorPaintings(torch.from_numpy(image), crop=crop).painting(0, config.image_size)
        arrays.append(render_arrays(renderer, sequence, painting, config, position, rng=rng, homographies=homographies))
    return arrays


_HEADER = struct.Struct("!Q")
"""A message's length in bytes, before its pickle."""


class _Outgoing:
    """One message on its way out: its bytes and how many a socket took so far."""

    def __init__(self, message: Any):
        payload = pickle.dumps(message, protocol=pickle.HIGHEST_PROTOCOL)
        self.data, self.sent = memoryview(_HEADER.pack(len(payload)) + payload), 0

    def pump(self, sock: socket.socket) -> bool:
        """Send what ``sock`` takes now (all of it on a blocking socket); whether the message is out.

        Raises:
            OSError: the other end is gone (``BrokenPipeError``, ``ConnectionResetError``).
        """
        while self.sent < len(self.data):
            try:
                self.sent += sock.send(self.data[self.sent:])
            except BlockingIOError:
                return False
        return True

    @property
    def done(self) -> bool:
        return self.sent == len(self.data)


class _Incoming:
    """One message on its way in: its length once its header is in, then its bytes."""

    def __init__(self):
        self.buffer, self.got, self.size = bytearray(_HEADER.size), 0, None

    def pump(self, sock: socket.socket) -> bool:
        """Read what ``sock`` holds now (all of the message on a blocking socket); whether it is complete.

        Raises:
            EOFError: the other end closed before the message was complete.
            OSError: the connection broke (``ConnectionResetError``).
        """
        while True:
            try:
                count = sock.recv_into(memoryview(self.buffer)[self.got:])
            except BlockingIOError:
                return False
            if count == 0:
                raise EOFError("the connection closed in the middle of a message" if self.got else "closed")
            self.got += count
            if self.got == len(self.buffer):
                if self.size is not None:
                    return True
                (self.size,) = _HEADER.unpack(self.buffer)
                self.buffer, self.got = bytearray(self.size), 0

    def message(self) -> Any:
        return pickle.loads(self.buffer)


@dataclasses.dataclass
class _Job:
    """What the parent is doing with one worker: ``what`` it waits for (``"image 3 of the batch"``,
    ``"the warm-up"``), the task still being sent (``None``: nothing to send) and the reply coming in."""

    what: str
    outgoing: _Outgoing | None
    incoming: _Incoming = dataclasses.field(default_factory=_Incoming)

    @property
    def sending(self) -> bool:
        return self.outgoing is not None and not self.outgoing.done

    def stage(self) -> str:
        """Where the job stands: ``"image 0 of the batch: 212992 of 589951 bytes of the task sent"``."""
        if self.sending:
            return f"{self.what}: {self.outgoing.sent} of {len(self.outgoing.data)} bytes of the task sent"
        if self.incoming.size is None and self.incoming.got == 0:
            return f"{self.what}: no reply yet"
        return f"{self.what}: {self.incoming.got} of {self.incoming.size or '?'} bytes of its reply received"


class RenderPool:
    """``num_workers`` forked render processes for one config and crop mode.

    Args:
        config, crop: what every task is rendered with (copied into the workers at the fork).
        num_workers: number of processes, from 1 to :data:`sidar_torch.config.MAX_WORKERS` (256:
            each holds its own renderer, about 100 MiB, and renders on one CPU thread).
        warm_up_timeout: the most seconds the constructor waits for every worker to warm up (compile
            the shader variants of ``config``, :func:`sidar_torch.sample.warm_up.warm_up_renderer`; at once
            when the parent's renderer was warm at the fork); ``0``: no limit. Any finite number
            (see :data:`LONGEST_WAIT_S`).

    The processes start and warm up in the constructor and live until :meth:`close` (also called
    when the pool is garbage-collected and at interpreter exit). A worker exits by itself within a
    second of its parent's death (see the module docstring). A pool belongs to the process that made
    it: a forked copy of it (e.g. inside a DataLoader worker) is :attr:`usable` nowhere but there.

    Raises:
        ValueError: ``num_workers`` out of its range (before any process starts).
        TimeoutError: a worker did not warm up within ``warm_up_timeout`` (naming its pid and state);
            the exception a worker's warm-up raised (no GL context, ...). The workers are ended.
    """

    def __init__(self, config: SidarConfig, crop: str, num_workers: int, warm_up_timeout: float = 0.0):
        num_workers = as_int("num_workers", num_workers, 1, MAX_WORKERS)
        context = multiprocessing.get_context("fork")
        preload()  # the workers inherit the renderer's imports
        self.pid = os.getpid()
        # Linux's parent-death signal follows the forking thread: SIGKILL only if that is the main thread.
        death_signal = threading.current_thread() is threading.main_thread()
        self._sockets: list[socket.socket] = []
        processes = []
        for _ in range(num_workers):
            parent_end, child_end = socket.socketpair()
            inherited = open_descriptors() - {child_end.fileno()}  # what the worker lets go of
            process = context.Process(target=_worker_main, daemon=True, name="sidar-augment-render",
                                      args=(child_end, config, crop, self.pid, death_signal, inherited))
            process.start()
            child_end.close()
            parent_end.setblocking(False)  # the parent never waits on one worker: see _step
            self._sockets.append(parent_end)
            processes.append(process)
        self.processes = processes
        self._finalizer = weakref.finalize(self, _shut_down, self.pid, self._sockets, processes)
        jobs, deadline = {sock: _Job("the warm-up", None) for sock in self._sockets}, _deadline(warm_up_timeout)
        try:
            while jobs:
                for sock, (status, payload) in self._step(jobs, deadline, "warm_up_timeout", warm_up_timeout):
                    del jobs[sock]
                    if status != "ok":
                        raise payload
        except BaseException:
            self.close()
            raise

    @property
    def usable(self) -> bool:
        """Whether this process owns the pool and it is open."""
        return self._finalizer.alive and os.getpid() == self.pid

    def run(self, tasks: Sequence[RenderTask], timeout: float = 0.0) -> list[SampleArrays]:
        """Render every task, each in whichever worker is free; the results in the tasks' order.

        Args:
            tasks: what to render.
            timeout: the most seconds the whole call may take: sending the tasks, rendering them and
                receiving the results (``0``: no limit; any finite number, see :data:`LONGEST_WAIT_S`).
                The workers are warm (see the constructor): no shader compilation falls in it.

        Raises:
            The exception a worker raised (its traceback in the exception's notes), after the
            other workers finished their tasks (the pool stays open); ``RuntimeError`` naming the
            worker if one died, ``TimeoutError`` naming every worker still busy at the deadline,
            its pid, its state (e.g. stopped) and what it was doing: the pool is then closed, its
            workers ended.
        """
        if not self.usable:
            raise RuntimeError("RenderPool.run: the pool is closed or belongs to another process")
        deadline = _deadline(timeout)
        results: list[SampleArrays | None] = [None] * len(tasks)
        pending = list(reversed(range(len(tasks))))
        jobs: dict[socket.socket, _Job] = {}
        positions: dict[socket.socket, int] = {}
        error: BaseException | None = None

        def hand_out(sock: socket.socket) -> None:
            index = pending.pop()
            jobs[sock], positions[sock] = _Job(f"image {index} of the batch", _Outgoing(tasks[index])), index

        try:
            for sock in self._sockets:
                if pending:
                    hand_out(sock)
            while jobs:
                for sock, (status, payload) in self._step(jobs, deadline, "timeout", timeout):
                    del jobs[sock]
                    if status == "ok":
                        results[positions[sock]] = payload
                    elif error is None:
                        error = payload
                    if pending and error is None:
                        hand_out(sock)
        except BaseException:
            self.close()  # a worker died or hangs, or the caller was interrupted with tasks in flight
            raise
        if error is not None:
            raise error
        return results  # type: ignore[return-value]

    def _step(self, jobs: dict[socket.socket, _Job], deadline: float, limit_name: str,
              limit: float) -> list[tuple[socket.socket, Any]]:
        """Wait (until ``deadline`` at most, on ``time.monotonic``, and :data:`LONGEST_WAIT_S`) for a
        socket of ``jobs`` to be ready, move what it can of each job's task out and of its reply in,
        and return the ``(socket, reply)`` of the jobs whose reply is complete (none if the wait
        ended first).

        Raises:
            TimeoutError: the deadline passed with ``jobs`` unfinished (``limit_name=limit`` named).
            RuntimeError: a worker died (its socket closed).
        """
        left = deadline - time.monotonic()
        if left <= 0:
            raise self._timed_out(jobs, limit_name, limit)
        with selectors.DefaultSelector() as selector:
            for sock, job in jobs.items():
                selector.register(sock, selectors.EVENT_READ | (selectors.EVENT_WRITE if job.sending else 0))
            ready = [(key.fileobj, events) for key, events in selector.select(min(left, LONGEST_WAIT_S))]
        done = []
        try:
            for sock, events in ready:
                if events & selectors.EVENT_WRITE and jobs[sock].sending:  # epoll reports a hang-up as both
                    jobs[sock].outgoing.pump(sock)
            for sock, events in ready:
                if events & selectors.EVENT_READ and jobs[sock].incoming.pump(sock):
                    done.append((sock, jobs[sock].incoming.message()))
        except (EOFError, OSError):  # BrokenPipeError, ConnectionResetError, a closed socket: the worker is gone
            raise self._died(sock) from None
        return done

    def _worker(self, sock: socket.socket) -> Any:
        return self.processes[self._sockets.index(sock)]

    def _died(self, sock: socket.socket) -> RuntimeError:
        process = self._worker(sock)
        process.join(1.0)
        how = f"exit code {process.exitcode}" if process.exitcode is not None else process_state(process.pid)
        return RuntimeError(f"SidarAugment render worker (pid {process.pid}) died with {how}")

    def _timed_out(self, jobs: dict[socket.socket, _Job], limit_name: str, limit: float) -> TimeoutError:
        workers = "; ".join(f"worker pid {self._worker(sock).pid} ({process_state(self._worker(sock).pid)}), "
                            f"{job.stage()}" for sock, job in jobs.items())
        return TimeoutError(f"SidarAugment render pool: not done within {limit_name}={limit} s: {workers}. "
                            f"The render pool is closed, its workers ended (the next call starts a new one)")

    def close(self) -> None:
        """Stop the workers (safe to call twice; does nothing in a process that does not own the pool)."""
        if os.getpid() == self.pid:
            self._finalizer()
        else:
            self._finalizer.detach()


def _deadline(limit: float) -> float:
    """The ``time.monotonic`` time ``limit`` seconds from now (``0``: no limit, infinity)."""
    return time.monotonic() + limit if limit > 0 else math.inf


def _shut_down(pid: int, sockets: list[socket.socket], processes: list) -> None:
    """Ask each worker to stop (closing its socket), then end them (``orphans.end_processes``)."""
    if os.getpid() != pid:
        return
    for sock in sockets:
        sock.close()
    end_processes(processes)


def _worker_main(sock: socket.socket, config: SidarConfig, crop: str, parent_pid: int,
                 death_signal: bool, inherited: set[int]) -> None:
    """Warm up, say so (``("ok", None)`` or ``("error", exception)``), then render tasks from ``sock``
    until it closes or the parent dies (``inherited``: the parent's descriptors at the fork, less
    ``sock``'s). Every reply is ``("ok", SampleArrays)`` or ``("error", exception)``."""
    exit_with_parent(parent_pid, death_signal=death_signal)
    release_inherited_descriptors(inherited)
    torch.set_num_threads(1)
    forks_nothing()  # a worker forks nothing: Mesa's disk cache may serve its shader variants

    renderer = None

    def warm_up() -> None:
        nonlocal renderer
        renderer = shared_renderer(RenderSettings.from_config(config))  # this worker's, for its life
        warm_up_renderer(renderer, config)

    reply = _attempt(warm_up)
    while True:
        try:
            _Outgoing(reply).pump(sock)
            incoming = _Incoming()
            incoming.pump(sock)
        except (EOFError, OSError):  # the pool closed this socket, or the parent died
            return
        reply = _attempt(lambda: render_tasks(renderer, config, crop, [incoming.message()])[0])


def _attempt(work: Callable[[], Any]) -> tuple[str, Any]:
    """``("ok", work())``, or ``("error", exception)`` with the exception ``work`` raised (``orphans.portable_exception``),
    which the caller raises."""
    try:
        return "ok", work()
    except Exception as exc:
        return "error", portable_exception(exc, f"SidarAugment render worker (pid {os.getpid()})")
