"""Rendering one :class:`sidar_torch.SidarAugment` image, in this process or in a pool of render processes.

A *task* is everything image ``b`` of a call needs: its position, the entropy of its generator
(``numpy.random.default_rng(entropy)`` draws the scene, then the view effects) and its pixels,
``(3, h, w)`` uint8. :func:`render_tasks` turns tasks into :class:`~sidar_torch.sample.SampleArrays`;
it is the only rendering path, whichever process runs it: all of a batch without a pool, one task at
a time in a pool worker. It fits the homographies of the tasks it is given in one Kornia call, which
gives each sequence the values it gets alone (``sample.batch_homographies``), so neither the pixels
nor the geometry depend on the pool.

:class:`RenderPool` keeps ``n`` forked processes, each with its own renderer (its copy of the
parent's, or one created and warmed up at its first task, ``sidar_torch.warm_up``; then reused),
fed one task at a time through its own pipe: a process that finishes takes the next task, and
results are put back in batch order.

A worker ends with its parent, whatever it is doing (rendering, waiting, or blocked sending a reply
no one reads): right after the fork it calls :func:`sidar_torch.orphans.exit_with_parent` and lets
go of every descriptor it inherited but its own pipe end (the parent's ends of every pipe, its own
included, and any file of the parent's), see :mod:`sidar_torch.orphans`.

Processes are forked (``fork`` start method): a worker starts in milliseconds, where ``spawn`` or
``forkserver`` pay about 2 s of imports each. This is safe after the parent rendered because
``sidar_torch.render`` sets ``LP_NUM_THREADS=0`` (llvmpipe keeps no threads that a child would
miss) and disables Mesa's on-disk shader cache in the parent; a child takes over its copy of the
parent's renderer, with every shader variant the parent compiled (see
:func:`sidar_torch.render.shared_renderer`).
"""

from __future__ import annotations

import math
import multiprocessing
import os
import pickle
import threading
import time
import traceback
import weakref
from multiprocessing.connection import Connection, wait
from typing import Any, Sequence

import numpy as np
import torch

from .config import SidarConfig
from .orphans import exit_with_parent, open_descriptors, release_inherited_descriptors
from .render import preload
from .render.context import forks_nothing
from .sample import SampleArrays, batch_homographies, render_arrays
from .scene import sample_sequence
from .paintings import TensorPaintings

__all__ = ["RenderPool", "RenderTask", "render_tasks"]

RenderTask = tuple[int, Sequence[int], np.ndarray]
"""``(position, entropy, image)``: image ``position`` of the batch, the entropy of its generator
(a list of non-negative integers) and its pixels ``(3, h, w)`` uint8."""


def render_tasks(config: SidarConfig, crop: str, tasks: Sequence[RenderTask]) -> list[SampleArrays]:
    """Draw the scene of each task, fit all their homographies in one call, and render each scene
    with its task's image fitted to ``config.image_size``."""
    rngs = [np.random.default_rng(list(entropy)) for _, entropy, _ in tasks]
    sequences = [sample_sequence(config, rng) for rng in rngs]
    arrays = []
    for (position, _, image), rng, sequence, homographies in zip(tasks, rngs, sequences, batch_homographies(sequences)):
        painting = TensorPaintings(torch.from_numpy(image), crop=crop).painting(0, config.image_size)
        arrays.append(render_arrays(sequence, painting, config, position, rng=rng, homographies=homographies))
    return arrays


class RenderPool:
    """``num_workers`` forked render processes for one config and crop mode.

    Args:
        config, crop: what every task is rendered with (copied into the workers at the fork).
        num_workers: number of processes (``>= 1``).

    The processes start in the constructor and live until :meth:`close` (also called when the pool
    is garbage-collected and at interpreter exit). A worker exits by itself within a second of its
    parent's death (see the module docstring). A pool belongs to the process that made it: a forked
    copy of it (e.g. inside a DataLoader worker) is :attr:`usable` nowhere but there.
    """

    def __init__(self, config: SidarConfig, crop: str, num_workers: int):
        context = multiprocessing.get_context("fork")
        preload()  # the workers inherit the renderer's imports
        self.pid = os.getpid()
        # Linux's parent-death signal follows the forking thread: armed only if that is the main thread.
        death_signal = threading.current_thread() is threading.main_thread()
        self._connections: list[Connection] = []
        processes = []
        for _ in range(num_workers):
            parent_end, child_end = context.Pipe()
            inherited = open_descriptors() - {child_end.fileno()}  # what the worker lets go of
            process = context.Process(target=_worker_main, daemon=True, name="sidar-augment-render",
                                      args=(child_end, config, crop, self.pid, death_signal, inherited))
            process.start()
            child_end.close()
            self._connections.append(parent_end)
            processes.append(process)
        self.processes = processes
        self._finalizer = weakref.finalize(self, _shut_down, self.pid, self._connections, processes)

    @property
    def usable(self) -> bool:
        """Whether this process owns the pool and it is open."""
        return self._finalizer.alive and os.getpid() == self.pid

    def run(self, tasks: Sequence[RenderTask], timeout: float = 0.0) -> list[SampleArrays]:
        """Render every task, each in whichever worker is free; the results in the tasks' order.

        Args:
            tasks: what to render.
            timeout: the most seconds to wait, after sending a worker a task, for its result to
                start arriving (``0``: no limit). As with ``DataLoader``'s timeout, a worker stopped
                in the middle of sending a result is not covered.

        Raises:
            The exception a worker raised (its traceback in the exception's notes), after the
            other workers finished their tasks; ``RuntimeError`` if a worker died, ``TimeoutError``
            naming the worker if one sent no result within ``timeout`` (the pool is then closed).
        """
        if not self.usable:
            raise RuntimeError("RenderPool.run: the pool is closed or belongs to another process")
        limit = timeout if timeout > 0 else math.inf
        results: list[SampleArrays | None] = [None] * len(tasks)
        pending = list(reversed(range(len(tasks))))
        busy: dict[Connection, tuple[int, float]] = {}  # connection -> (task, deadline on time.monotonic)
        error: BaseException | None = None

        def hand_out(connection: Connection) -> None:
            index = pending.pop()
            self._send(connection, tasks[index])
            busy[connection] = index, time.monotonic() + limit

        try:
            for connection in self._connections:
                if pending:
                    hand_out(connection)
            while busy:
                first = min(busy, key=lambda c: busy[c][1])
                left = busy[first][1] - time.monotonic()
                ready = wait(list(busy), None if math.isinf(left) else max(left, 0.0))
                if not ready and time.monotonic() >= busy[first][1]:
                    raise self._timed_out(first, busy[first][0], timeout)
                for connection in ready:
                    index, _ = busy.pop(connection)
                    status, payload = self._receive(connection)
                    if status == "ok":
                        results[index] = payload
                    elif error is None:
                        error = payload
                    if pending and error is None:
                        hand_out(connection)
        except BaseException:
            self.close()  # a worker died or hangs, or the caller was interrupted with tasks in flight
            raise
        if error is not None:
            raise error
        return results  # type: ignore[return-value]

    def _send(self, connection: Connection, task: RenderTask) -> None:
        try:
            connection.send(task)
        except OSError:  # BrokenPipeError: the worker is gone
            raise self._died(connection) from None

    def _receive(self, connection: Connection) -> tuple[str, Any]:
        try:
            return connection.recv()
        except (EOFError, OSError):
            raise self._died(connection) from None

    def _worker(self, connection: Connection) -> Any:
        return self.processes[self._connections.index(connection)]

    def _died(self, connection: Connection) -> RuntimeError:
        process = self._worker(connection)
        process.join(1.0)
        return RuntimeError(f"SidarAugment render worker (pid {process.pid}) died with exit code {process.exitcode}")

    def _timed_out(self, connection: Connection, index: int, timeout: float) -> TimeoutError:
        return TimeoutError(f"SidarAugment render worker (pid {self._worker(connection).pid}) sent no result for "
                            f"image {index} of the batch within timeout={timeout} s; the render pool is closed "
                            "(the next call starts a new one)")

    def close(self) -> None:
        """Stop the workers (safe to call twice; does nothing in a process that does not own the pool)."""
        if os.getpid() == self.pid:
            self._finalizer()
        else:
            self._finalizer.detach()


def _shut_down(pid: int, connections: list[Connection], processes: list) -> None:
    """Ask each worker to stop (closing its pipe), wait a little, then terminate stragglers and kill
    those that do not end (a stopped process does not act on SIGTERM)."""
    if os.getpid() != pid:
        return
    for connection in connections:
        connection.close()
    for process in processes:
        process.join(2.0)
        for end in (process.terminate, process.kill):
            if process.is_alive():
                end()
                process.join(1.0)


def _worker_main(connection: Connection, config: SidarConfig, crop: str, parent_pid: int,
                 death_signal: bool, inherited: set[int]) -> None:
    """Render tasks from ``connection`` until it closes or the parent dies (``inherited``: the
    parent's descriptors at the fork, less ``connection``'s)."""
    exit_with_parent(parent_pid, death_signal=death_signal)
    release_inherited_descriptors(inherited)
    torch.set_num_threads(1)
    forks_nothing()  # a worker forks nothing: Mesa's disk cache may serve its shader variants
    while True:
        try:
            task = connection.recv()
        except (EOFError, OSError):  # the pool closed this pipe, or the parent died
            return
        try:
            reply = ("ok", render_tasks(config, crop, [task])[0])
        except Exception as exc:  # sent to the caller, which raises it
            reply = ("error", _portable(exc))
        try:
            connection.send(reply)
        except OSError:  # BrokenPipeError: the parent is gone
            return


def _portable(exc: Exception) -> BaseException:
    """``exc`` with the worker's traceback as a note, or a ``RuntimeError`` with its text if it does
    not survive pickling."""
    text = "".join(traceback.format_exception(exc))
    try:
        copy = pickle.loads(pickle.dumps(exc))
    except Exception:
        copy = RuntimeError(f"{type(exc).__name__}: {exc}")
    copy.add_note(f"raised in SidarAugment render worker (pid {os.getpid()}):\n{text}")
    return copy
