"""``export_dataset``: freeze sequences of a :class:`~sidar_torch.SidarDataset` to disk.

Sequences are rendered (here, or in DataLoader workers) as :class:`sidar_torch.sample.SampleArrays`
and written unit by unit by the export's layout (:data:`.layouts.LAYOUTS`): :mod:`.folders` (the
paper's, the default) or :mod:`.shards`.
"""

from __future__ import annotations

import dataclasses
import os
import signal
import sys
import threading
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Callable, Iterator, TextIO

from torch.utils.data import DataLoader, Dataset

from ..config import MAX_WORKERS, as_int
from ..data.dataset import SidarDataset
from ..orphans import exit_with_parent
from ..sample import SampleArrays
from .files import locked, remove_stale
from .layout import Layout, WriteUnit
from .layouts import layout_for
from .manifest import write_manifest


@dataclasses.dataclass(frozen=True)
class ExportSummary:
    """What :func:`export_dataset` did.

    Attributes:
        out: the export folder.
        written: dataset indices rendered and written by this call, ascending.
        present: how many of the requested indices an earlier run had already written.
        seconds: wall-clock time of the call.
    """

    out: Path
    written: tuple[int, ...]
    present: int
    seconds: float


class ExportInterrupted(KeyboardInterrupt):
    """An export stopped by Ctrl-C (``KeyboardInterrupt``); what it wrote is complete and kept, and
    the same call (or command) again resumes.

    Attributes:
        out: the export folder.
        done: how many of the requested sequences are in ``out``.
        requested: how many were requested.
    """

    def __init__(self, out: Path, done: int, requested: int):
        super().__init__(f"export into {str(out)!r} interrupted after {done} of {requested} sequences; "
                         f"export again with the same arguments to resume")
        self.out, self.done, self.requested = out, done, requested


def export_dataset(dataset: SidarDataset, out_dir: str | os.PathLike, count: int, start: int = 0,
                   shard_size: int | None = None, workers: int = 0, progress: bool = True, *,
                   shards: int | None = None, layout: str | None = None) -> ExportSummary:
    """Write sequences ``start .. start + count - 1`` of ``dataset`` to ``out_dir`` (see :mod:`sidar_torch.io`).

    Args:
        dataset: the :class:`SidarDataset` to freeze (its config, seed and painting source are
            recorded in ``export.json``).
        out_dir: the export folder; created if missing. Rerunning into it resumes.
        count: number of sequences, ``>= 1``.
        start: first dataset index, ``>= 0``.
        shard_size: ``None`` for the folder layout, or ``N >= 1``: tar shards of (at most) ``N``
            sequences each.
        workers: ``0`` renders in this process; ``n >= 1`` (at most ``config.MAX_WORKERS``) renders in
            ``n`` DataLoader workers while this process writes.
        progress: print a progress line on stderr (redrawn in place on a terminal, else every 10 s).
        shards: the older name of ``shard_size``, still accepted.
        layout: a name of :data:`.layouts.LAYOUTS` (``"paper"``: the SIDAR paper's files, see
            :mod:`.paper`); ``None``: folders, or shards with ``shard_size``.

    Returns:
        An :class:`ExportSummary`.

    Raises:
        TypeError: ``dataset`` is not a :class:`SidarDataset`.
        ValueError: a bad ``count``, ``start``, ``shard_size`` or ``workers``; ``out_dir`` holds an
            export whose seed, source, config, layout or version differ, or files that are not an export's.
        RuntimeError: another export holds the lock on ``out_dir``.
        ExportInterrupted: Ctrl-C (a ``KeyboardInterrupt``) stopped it; what it wrote is kept.
    """
    begin = time.perf_counter()
    workers = as_int("workers", workers, 0, MAX_WORKERS)
    with planned_export(dataset, out_dir, count, start, either_shard_size(shard_size, shards), layout) as plan:
        with Progress(len(plan.missing), sys.stderr if progress else None) as bar, ctrl_c_between() as check:
            take = _InOrder(_render(dataset, plan.missing, workers))

            def advance(*args: Any) -> None:
                bar.advance(*args)
                check()

            for unit in plan.units():
                plan.layout.write(plan.out, unit, take, advance)
    return ExportSummary(plan.out, tuple(plan.missing), len(plan.present), time.perf_counter() - begin)


@contextmanager
def ctrl_c_between() -> Iterator[Callable[[], None]]:
    """Hold a first Ctrl-C until the block calls the function this yields (raising
    ``KeyboardInterrupt`` there, between two written sequences); a second Ctrl-C raises at once.

    A ``KeyboardInterrupt`` raised wherever the signal lands can land inside ctypes' conversion of a
    GL call's argument, which turns it into a ``ctypes.ArgumentError``: a traceback instead of
    :class:`ExportInterrupted`. Outside the main thread (where Python cannot take signals) the
    block runs as it is and the function does nothing.
    """
    if threading.current_thread() is not threading.main_thread():
        yield lambda: None
        return
    pressed: list[bool] = []

    def hold(signum: int, frame: Any) -> None:
        if pressed:
            raise KeyboardInterrupt
        pressed.append(True)

    def check() -> None:
        if pressed:
            raise KeyboardInterrupt

    previous = signal.signal(signal.SIGINT, hold)
    try:
        yield check
    finally:
        signal.signal(signal.SIGINT, previous)


def either_shard_size(shard_size: int | None, shards: int | None) -> int | None:
    """``shard_size``, or ``shards`` (its older name) if only that is given.

    Raises:
        ValueError: both are given.
    """
    if shards is None:
        return shard_size
    if shard_size is not None:
        raise ValueError(f"shards={shards!r}: the older name of shard_size; pass shard_size only")
    return shards


@dataclasses.dataclass(frozen=True)
class ExportPlan:
    """What an export into a prepared folder has to write (see :func:`planned_export`).

    Attributes:
        out: the export folder.
        layout: the export's layout (a :class:`~.layout.Layout`).
        present: the requested indices an earlier run already wrote.
        missing: the requested indices to render and write, ascending.
        damaged: the numbers of the layout's units to rewrite whole because they are damaged (a
            truncated shard).
    """

    out: Path
    layout: Layout
    present: set[int]
    missing: list[int]
    damaged: frozenset[int] = frozenset()

    def units(self) -> list[WriteUnit]:
        """The layout's write units that add the ``missing`` sequences or rewrite the ``damaged``
        units, ascending (see :meth:`.layout.Layout.groups`)."""
        return self.layout.groups(self.missing, self.damaged)


class _InOrder:
    """``render`` for :meth:`.layout.Layout.write` from samples that arrive in the order of the
    plan's missing indices: each call takes the next one and checks it is the index asked for."""

    def __init__(self, samples: Iterator[SampleArrays]):
        self.samples = samples

    def __call__(self, index: int) -> SampleArrays:
        """The next sample, which is sequence ``index``'s (``RuntimeError`` otherwise: a bug)."""
        sample = next(self.samples)
        if sample.index != index:
            raise RuntimeError(f"internal: the export expected sequence {index}, got {sample.index}")
        return sample


@contextmanager
def planned_export(dataset: SidarDataset, out_dir: str | os.PathLike, count: int, start: int,
                   shard_size: int | None, layout_name: str | None = None) -> Iterator[ExportPlan]:
    """The part every export shares, local or distributed: check the arguments, create ``out_dir``,
    hold its lock for the block, write (or check) the manifest, delete stale temporaries and find what
    is missing. The block writes the :class:`ExportPlan`'s units with its layout; a
    ``KeyboardInterrupt`` in it becomes an :class:`ExportInterrupted` saying how many are done.

    Raises:
        the exceptions of :func:`export_dataset` (but for ``workers``).
    """
    if not isinstance(dataset, SidarDataset):
        raise TypeError(f"dataset: expected a SidarDataset, got {type(dataset).__name__}")
    count, start = as_int("count", count, 1), as_int("start", start, 0)
    layout = layout_for(shard_size, layout_name)
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise NotADirectoryError(f"out_dir: {str(out)!r} exists and is not a folder")
    out.mkdir(parents=True, exist_ok=True)
    with locked(out):
        write_manifest(out, dataset.seed, dataset.source, dataset.config.to_dict(), layout)
        remove_stale(out)
        wanted = range(start, start + count)
        present, damaged = layout.present(out, wanted)
        try:
            yield ExportPlan(out, layout, present, [i for i in wanted if i not in present], damaged)
        except KeyboardInterrupt:
            raise ExportInterrupted(out, len(layout.present(out, wanted)[0]), count) from None


class _Renders(Dataset):
    """Map-style view of the indices to render: item ``k`` is the :class:`SampleArrays` of ``indices[k]``."""

    def __init__(self, dataset: SidarDataset, indices: list[int]):
        self.dataset, self.indices = dataset, indices

    def __len__(self) -> int:
        return len(self.indices)

    def __getitem__(self, k: int) -> SampleArrays:
        return self.dataset.sample_arrays(self.indices[k])


def _keep(item: Any) -> Any:
    """DataLoader ``collate_fn`` that hands items over unchanged (picklable, unlike a lambda)."""
    return item


def _render(dataset: SidarDataset, indices: list[int], workers: int) -> Iterator[SampleArrays]:
    """The samples of ``indices``, in order, rendered here (``workers=0``) or in DataLoader workers."""
    if workers == 0 or not indices:
        return (dataset.sample_arrays(index) for index in indices)
    return iter(DataLoader(_Renders(dataset, indices), batch_size=None, num_workers=workers, collate_fn=_keep,
                           worker_init_fn=_exit_with_parent))


def _exit_with_parent(worker_id: int) -> None:
    """DataLoader ``worker_init_fn``: end this worker as soon as the export's process is gone.

    PyTorch's workers notice a dead parent only between tasks and then wait for their result queue
    to drain, which no one reads any more: after a ``kill -9`` of the export they stayed alive for
    good. :func:`~sidar_torch.orphans.exit_with_parent` leaves at once (nothing of the worker's is
    worth saving: the export writes only what reached it, atomically); with SIGCONT as its death
    signal rather than SIGKILL, as the worker cannot know which of its parent's threads forked it
    (SIGCONT wakes a stopped worker, whose watcher then sees the parent gone)."""
    exit_with_parent(os.getppid(), death_signal=False)


class Progress:
    """``export: 12/100 sequences, 0.41 s each, 36 s left`` on ``stream``: redrawn in place on a
    terminal, else printed every 10 s and at the end; ``stream=None`` prints nothing. Used as a
    context manager: the last line is drawn on a normal exit, a live line is ended on an exception.

    The time left is :func:`seconds_left` of the work reported: sequences done locally (one after
    the other, the time per sequence is the time since the start over the sequences done), or tasks
    done in parallel that report their own busy time (Ray), so that neither start-up nor a batch
    finishing at once skews it.
    """

    def __init__(self, total: int, stream: TextIO | None):
        self.total, self.stream, self.done, self.busy, self.parallel = total, stream, 0, None, 1
        self.drawn = -1  # ``done`` when the line was last drawn
        self.start = self.last = time.perf_counter()
        self.live = stream is not None and stream.isatty()
        self._show(force=True)

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, kind: type | None, *_: Any) -> None:
        if kind is None and (self.live or self.drawn != self.done):
            self._show(force=True)
        if self.live:
            self.stream.write("\n")

    def advance(self, count: int = 1, busy: float | None = None, parallel: int = 1) -> None:
        """``count`` more sequences are done; ``busy``: seconds a worker spent on them (parallel
        work), ``parallel``: how many workers share the work left."""
        self.done += count
        if busy is not None:
            self.busy = (self.busy or 0.0) + busy
        self.parallel = parallel
        self._show(force=False)

    def seconds_left(self, now: float) -> float:
        """The estimated seconds to finish, at time ``now`` (``perf_counter``); needs ``done >= 1``."""
        per_sequence = (now - self.start) / self.done if self.busy is None else self.busy / self.done
        return seconds_left(self.total - self.done, per_sequence, self.parallel)

    def _show(self, force: bool) -> None:
        if self.stream is None:
            return
        now = time.perf_counter()
        if not (force or self.live or now - self.last >= 10):
            return
        self.last, self.drawn = now, self.done
        line = f"export: {self.done}/{self.total} sequences"
        if self.done:
            line += f", {(now - self.start) / self.done:.2f} s each, {self.seconds_left(now):.0f} s left"
        self.stream.write(("\r" + line + "\033[K") if self.live else line + "\n")
        self.stream.flush()


def seconds_left(remaining: int, seconds_per_sequence: float, parallel: int = 1) -> float:
    """Seconds to do ``remaining`` sequences that take ``seconds_per_sequence`` each, ``parallel`` at a time."""
    return remaining * seconds_per_sequence / max(parallel, 1)
