"""WebDataset-style tar shards: shard ``k`` holds the sequences with indices in ``[k N, (k + 1) N)``.

``shard-00000.tar``, ``shard-00001.tar``, ... hold, in index order, entries named
``<key>.<name>`` with ``key`` the 6-digit index: the shared entries (``000007.0.png``,
``000007.0-m.png``, ``000007.0-o.png`` with ``opacity_output``, ``000007.0-s.png`` with
``shadow_mask_output``, ..., ``000007.gt.png``, ``000007.cameras.json``) and ``000007.homographies.npy`` (all ``(V, V, 3, 3)`` float64), so
``webdataset.WebDataset("out/shard-{00000..00009}.tar")`` reads them too. Entries have mode 644
and time 0: equal data gives equal tars.
"""

from __future__ import annotations

import io
import os
import tarfile
import itertools
from contextlib import nullcontext
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, ClassVar

import numpy as np

from ..config import MAX_VIEWS
from ..sample import KEYS, SampleArrays
from .files import open_inside, temporary_path
from .codecs import encode
from .entries import HOMOGRAPHIES, cameras_entry, checked_homographies, sample_entries
from .layout import SEQUENCE_NAME, SHARD_NAME, WriteUnit, sequence_name, shown_names

END_MARKER = 2 * tarfile.BLOCKSIZE
"""Bytes of zeros that end a whole tar (the end-of-archive marker ``tarfile`` writes)."""


def entries(arrays: SampleArrays) -> dict[str, Any]:
    """A sequence's entries by name (without the key): the shared entries, then ``homographies.npy``."""
    return {**sample_entries(arrays), HOMOGRAPHIES: arrays.homographies}


def shard_path(out: Path, shard: int) -> Path:
    return out / f"shard-{shard:05d}.tar"


_VIEW_ENTRIES = sum(key.entry is not None and "{v}" in key.entry for key in KEYS)
MAX_SEQUENCE_ENTRIES = MAX_VIEWS * _VIEW_ENTRIES + sum(key.entry is not None for key in KEYS) - _VIEW_ENTRIES + 2
"""Most entries a sequence of a shard can hold: its per-view files for :data:`~sidar_torch.config.MAX_VIEWS`
views with every output, its whole-image ones, ``cameras.json`` and ``homographies.npy``."""


class _BoundedReads:
    """The regular file ``f`` of ``size`` bytes, whose ``read(n)`` asks for no more than the file holds
    after the current offset. ``tarfile`` reads a GNU long name or a pax header by the size its header
    claims, and Python reserves that many bytes before reading (a claim of 1e11: ``MemoryError``)."""

    def __init__(self, f: Any, size: int):
        self._f, self._size = f, size

    def read(self, n: int | None = -1) -> bytes:
        left = max(self._size - self._f.tell(), 0)
        return self._f.read(left if n is None or n < 0 else min(n, left))

    def seek(self, offset: int, whence: int = os.SEEK_SET) -> int:
        return self._f.seek(offset, whence)

    def tell(self) -> int:
        return self._f.tell()


class DamagedShard(ValueError):
    """A shard that is not a whole tar as the export writes it (cut short, say, by a copy that
    stopped). The message names the file; ``complete`` holds the sequences before the damage
    (``{index: [member, ...]}``, without the last one, which may have lost entries)."""

    def __init__(self, path: Path, reason: str, complete: dict[int, list[tarfile.TarInfo]]):
        super().__init__(f"{str(path)!r}: damaged shard ({reason}); rerun the export that wrote it to rewrite it")
        self.complete = complete


def shard_contents(path: Path, shard_size: int) -> dict[int, list[tarfile.TarInfo]]:
    """``{index: [member, ...]}`` of the shard at ``path`` (empty if there is none), a shard of
    ``shard_size`` sequences: shard ``k`` holds indices in ``[k N, (k + 1) N)``.

    Every read asks for at most what the file holds (:class:`_BoundedReads`), and an entry of a
    sequence that is not the shard's, or beyond the :data:`MAX_SEQUENCE_ENTRIES` a sequence can
    hold, ends the reading: memory and time are bounded by the file's size and by ``shard_size``.

    Raises:
        DamagedShard: the shard is truncated or not a tar of sequence entries.
        ValueError: ``path`` is not a regular file inside its folder (see :func:`.files.open_inside`).
    """
    if not os.path.lexists(path):
        return {}
    first = int(SHARD_NAME.match(path.name).group(1)) * shard_size
    contents: dict[int, list[tarfile.TarInfo]] = {}
    with open_inside(path, path.parent) as raw:
        size = os.fstat(raw.fileno()).st_size
        f = _BoundedReads(raw, size)
        try:
            with tarfile.open(fileobj=f, mode="r:") as tar:
                for member in tar:
                    key, dot, _ = member.name.partition(".")
                    if not (member.isfile() and dot and SEQUENCE_NAME.match(key)):
                        raise DamagedShard(path, f"entry {member.name!r} is not a sequence's file",
                                           _without_last(contents))
                    if not 0 <= member.size <= size - member.offset_data:  # tarfile reads base-256 sizes of any sign
                        raise DamagedShard(path, f"entry {member.name!r} declares {member.size} bytes from byte "
                                                 f"{member.offset_data}, the file has {size}", _without_last(contents))
                    if not first <= int(key) < first + shard_size:
                        raise DamagedShard(path, f"entry {member.name!r} is of sequence {int(key)}, not one of the "
                                                 f"shard's [{first}, {first + shard_size})", _without_last(contents))
                    members = contents.setdefault(int(key), [])
                    if len(members) == MAX_SEQUENCE_ENTRIES:
                        raise DamagedShard(path, f"sequence {key} has more than {MAX_SEQUENCE_ENTRIES} entries, the "
                                                 f"most one can hold (entry {member.name!r})", _without_last(contents))
                    members.append(member)
                end = tar.offset
        except (tarfile.TarError, OSError) as error:  # OSError: a seek past what the file system allows
            raise DamagedShard(path, f"{type(error).__name__}: {error}", _without_last(contents)) from None
        f.seek(end)
        if f.read(END_MARKER) != bytes(END_MARKER):
            raise DamagedShard(path, f"cut short: no end-of-archive marker after byte {end} of {size}",
                               _without_last(contents))
    return contents


def _without_last(contents: dict[int, list[tarfile.TarInfo]]) -> dict[int, list[tarfile.TarInfo]]:
    """``contents`` without its last sequence."""
    return dict(sorted(contents.items())[:-1])


def held_sequences(path: Path, shard_size: int) -> dict[int, list[tarfile.TarInfo]]:
    """What a rerun of the export keeps of the shard at ``path``: all of it, or of a damaged shard
    the sequences before the damage (the rerun rewrites it: :meth:`ShardLayout.write`)."""
    try:
        return shard_contents(path, shard_size)
    except DamagedShard as damaged:
        return damaged.complete


def _add_entry(tar: tarfile.TarFile, name: str, data: bytes) -> None:
    """Add file ``name`` holding ``data`` to ``tar`` (mode 644, time 0: equal data, equal tars)."""
    info = tarfile.TarInfo(name)
    info.size, info.mode, info.mtime = len(data), 0o644, 0
    tar.addfile(info, io.BytesIO(data))


@dataclass(frozen=True)
class ShardLayout:
    """The shard layout as a :class:`~.layout.Layout`: one write unit per tar shard of ``shard_size``
    sequences (shard ``k`` holds the indices in ``[k N, (k + 1) N)``)."""

    shard_size: int
    name: ClassVar[str] = "shards"
    units_per_task: ClassVar[int] = 1
    """Shards one Ray export task writes: one (a shard holds many sequences)."""

    @classmethod
    def from_record(cls, shard_size: Any) -> ShardLayout:
        """The layout of a manifest whose ``shard_size`` is ``shard_size``; ``ValueError`` unless it
        is an integer ``>= 1`` (not a bool)."""
        if type(shard_size) is not int or shard_size < 1:
            raise ValueError(f"field 'shard_size': expected an integer >= 1 for shards, got {shard_size!r}")
        return cls(shard_size)

    def present(self, out: Path, wanted: range) -> tuple[set[int], frozenset[int]]:
        """``(held, damaged)``: the indices of ``wanted`` (non-empty) that the shards in ``out`` hold
        whole, and the shards among ``wanted``'s that are damaged (to rewrite)."""
        held, damaged = set(), set()
        for shard in range(wanted.start // self.shard_size, (wanted.stop - 1) // self.shard_size + 1):
            try:
                contents = shard_contents(shard_path(out, shard), self.shard_size)
            except DamagedShard as error:
                contents = error.complete
                damaged.add(shard)
            held |= {i for i in contents if i in wanted}
        return held, frozenset(damaged)

    def groups(self, missing: list[int], damaged: frozenset[int]) -> list[WriteUnit]:
        """One unit per shard that lacks a sequence of ``missing`` or is ``damaged``, ascending."""
        units = {shard: () for shard in damaged}
        by_shard = itertools.groupby(missing, lambda index: index // self.shard_size)
        units.update((shard, tuple(new)) for shard, new in by_shard)
        return [WriteUnit(shard, new) for shard, new in sorted(units.items())]

    def write(self, out: Path, unit: WriteUnit, render: Callable[[int], SampleArrays],
              written: Callable[[], None]) -> None:
        """(Re)write shard ``unit.number``: the sequences it holds copied over (of a damaged shard,
        those before the damage), those of ``unit.indices`` it lacks made by ``render(index)``, all
        in index order, into ``.tmp-sidar-shard-<k>.tar``, then moved into place; ``written()`` is
        called after each sequence rendered."""
        path = shard_path(out, unit.number)
        old = held_sequences(path, self.shard_size)
        tmp = temporary_path(path)
        try:
            with tarfile.open(tmp, "w") as tar, (open_inside(path, out) if old else nullcontext()) as old_file:
                for index in sorted({*old, *unit.indices}):
                    if index in old:
                        for member in old[index]:
                            old_file.seek(member.offset_data)
                            _add_entry(tar, member.name, old_file.read(member.size))
                        continue
                    for name, data in encode(entries(render(index))).items():
                        _add_entry(tar, f"{sequence_name(index)}.{name}", data)
                    written()
            tmp.replace(path)
        except BaseException:
            tmp.unlink(missing_ok=True)
            raise

    def sequences(self, out: Path) -> list[tuple[int, dict[str, tuple[Path, int, int]]]]:
        """``(index, {entry name: (shard, offset, size)})`` of every sequence in the shards of ``out``, ascending.

        Raises:
            DamagedShard, ValueError: as :func:`shard_contents`, for any shard.
        """
        items = []
        for shard in sorted(p for p in out.iterdir() if SHARD_NAME.match(p.name)):
            for index, members in sorted(shard_contents(shard, self.shard_size).items()):
                items.append((index, {m.name.partition(".")[2]: (shard, m.offset_data, m.size) for m in members}))
        return items

    def read(self, out: Path, where: dict[str, tuple[Path, int, int]], name: str, limit: int) -> tuple[Path, bytes]:
        """``(shard, bytes)`` of entry ``name`` of the sequence whose entries are ``where``, at most
        ``limit`` bytes.

        Raises:
            FileNotFoundError: the sequence has no entry ``name``.
            ValueError: the entry is larger than ``limit`` bytes, or its shard is no longer a regular file.
        """
        if name not in where:
            shard = next(iter(where.values()))[0]
            raise FileNotFoundError(f"{str(shard)!r}: the sequence has no entry {name!r} (its entries, "
                                    f"{shown_names(sorted(where))})")
        shard, offset, size = where[name]
        if size > limit:
            raise ValueError(f"{str(shard)!r}: entry {name!r} holds {size} bytes, more than the {limit} "
                             f"this export's files can hold")
        with open_inside(shard, shard.parent) as f:
            f.seek(offset)
            return shard, f.read(size)

    def read_cameras(self, read: Callable[..., Any], config: dict[str, Any]) -> dict[str, np.ndarray]:
        """The checked cameras of the ``cameras.json`` entry (:func:`.entries.cameras_entry`)."""
        return cameras_entry(read, config)

    def read_homographies(self, read: Callable[..., Any], n_views: int) -> np.ndarray:
        """``(V, V, 3, 3)`` float64 from the ``homographies.npy`` entry (``read``: entry name, shape and
        check -> value), each checked (:func:`.entries.checked_homographies`)."""
        return read(HOMOGRAPHIES, (n_views, n_views, 3, 3), checked_homographies)
