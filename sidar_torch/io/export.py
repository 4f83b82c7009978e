"""``export_dataset``: freeze sequences of a :class:`~sidar_torch.SidarDataset` to disk.

Sequences are rendered (here, or in DataLoader workers) as :class:`sidar_torch.sample.SampleArrays`
and written by the layout's writer: :mod:`.folders` (the paper's, the default) or :mod:`.shards`.
"""

from __future__ import annotations

import dataclasses
import itertools
import os
import sys
import threading
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Iterator, TextIO

from torch.utils.data import DataLoader, Dataset

from ..config import as_int
from ..dataset import SidarDataset
from ..sample import SampleArrays
from . import folders
from . import shards as tar_shards  # the name "shards" is export_dataset's argument
from .layout import locked, remove_stale, write_manifest


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


def export_dataset(dataset: SidarDataset, out_dir: str | os.PathLike, count: int, start: int = 0,
                   shards: int | None = None, workers: int = 0, progress: bool = True) -> ExportSummary:
    """Write sequences ``start .. start + count - 1`` of ``dataset`` to ``out_dir`` (see :mod:`sidar_torch.io`).

    Args:
        dataset: the :class:`SidarDataset` to freeze (its config, seed and painting source are
            recorded in ``export.json``).
        out_dir: the export folder; created if missing. Rerunning into it resumes.
        count: number of sequences, ``>= 1``.
        start: first dataset index, ``>= 0``.
        shards: ``None`` for the folder layout, or ``N >= 1``: tar shards of (at most) ``N``
            sequences each.
        workers: ``0`` renders in this process; ``n >= 1`` renders in ``n`` DataLoader workers
            while this process writes.
        progress: print a progress line on stderr (redrawn in place on a terminal, else every 10 s).

    Returns:
        An :class:`ExportSummary`.

    Raises:
        TypeError: ``dataset`` is not a :class:`SidarDataset`.
        ValueError: a bad ``count``, ``start``, ``shards`` or ``workers``; ``out_dir`` holds an
            export whose seed, source, config, layout or version differ.
        RuntimeError: another export holds the lock on ``out_dir``.
    """
    begin = time.perf_counter()
    workers = as_int("workers", workers, 0)
    with planned_export(dataset, out_dir, count, start, shards) as plan:
        bar = Progress(len(plan.missing), sys.stderr if progress else None)
        samples = _render(dataset, plan.missing, workers)
        if plan.shard_size is None:
            for arrays in samples:
                folders.write_sequence(plan.out, arrays)
                bar.advance()
        else:
            for shard, new in plan.shards():
                tar_shards.write_shard(plan.out, shard, new, samples, bar.advance)
        bar.close()
    return ExportSummary(plan.out, tuple(plan.missing), len(plan.present), time.perf_counter() - begin)


@dataclasses.dataclass(frozen=True)
class ExportPlan:
    """What an export into a prepared folder has to write (see :func:`planned_export`).

    Attributes:
        out: the export folder.
        shard_size: ``None`` for the folder layout, else sequences per tar shard.
        present: the requested indices an earlier run already wrote.
        missing: the requested indices to render and write, ascending.
    """

    out: Path
    shard_size: int | None
    present: set[int]
    missing: list[int]

    def shards(self) -> list[tuple[int, list[int]]]:
        """``(shard, [missing index in it, ascending])`` for every shard that lacks a sequence (shard layout)."""
        groups = itertools.groupby(self.missing, key=lambda i: i // self.shard_size)
        return [(shard, list(new)) for shard, new in groups]


@contextmanager
def planned_export(dataset: SidarDataset, out_dir: str | os.PathLike, count: int, start: int,
                   shards: int | None) -> Iterator[ExportPlan]:
    """The part every export shares, local or distributed: check the arguments, create ``out_dir``,
    hold its lock for the block, write (or check) the manifest, delete stale temporaries and find what
    is missing. The block writes the :class:`ExportPlan`'s ``missing`` sequences with the layout's writer.

    Raises:
        the exceptions of :func:`export_dataset` (but for ``workers``).
    """
    if not isinstance(dataset, SidarDataset):
        raise TypeError(f"dataset: expected a SidarDataset, got {type(dataset).__name__}")
    count, start = as_int("count", count, 1), as_int("start", start, 0)
    shard_size = None if shards is None else as_int("shards", shards, 1)
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise NotADirectoryError(f"out_dir: {str(out)!r} exists and is not a folder")
    out.mkdir(parents=True, exist_ok=True)
    with locked(out):
        write_manifest(out, dataset.seed, dataset.source, dataset.config.to_dict(), shard_size)
        remove_stale(out)
        wanted = range(start, start + count)
        present = folders.present(out, wanted) if shard_size is None else tar_shards.present(out, wanted, shard_size)
        yield ExportPlan(out, shard_size, present, [i for i in wanted if i not in present])


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
    good. A daemon thread polls the parent's pid and leaves at once (nothing of the worker's is
    worth saving: the export writes only what reached it, atomically)."""
    parent = os.getppid()

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(0.2)
        os._exit(1)

    threading.Thread(target=watch, name="exit-with-parent", daemon=True).start()


class Progress:
    """``export: 12/100 sequences, 0.41 s each, 36 s left`` on ``stream``: redrawn in place on a
    terminal, else printed every 10 s and at the end; ``stream=None`` prints nothing."""

    def __init__(self, total: int, stream: TextIO | None):
        self.total, self.stream, self.done = total, stream, 0
        self.start = self.last = time.perf_counter()
        self.live = stream is not None and stream.isatty()
        self._show(force=True)

    def advance(self) -> None:
        self.done += 1
        self._show(force=False)

    def close(self) -> None:
        self._show(force=True)
        if self.live:
            self.stream.write("\n")

    def _show(self, force: bool) -> None:
        if self.stream is None:
            return
        now = time.perf_counter()
        if not (force or self.live or now - self.last >= 10):
            return
        self.last = now
        line = f"export: {self.done}/{self.total} sequences"
        if self.done:
            each = (now - self.start) / self.done
            line += f", {each:.2f} s each, {each * (self.total - self.done):.0f} s left"
        self.stream.write(("\r" + line + "\033[K") if self.live else line + "\n")
        self.stream.flush()
