"""WebDataset-style tar shards: shard ``k`` holds the sequences with indices in ``[k N, (k + 1) N)``.

``shard-00000.tar``, ``shard-00001.tar``, ... hold, in index order, entries named
``<key>.<name>`` with ``key`` the 6-digit index: the shared entries (``000007.0.png``,
``000007.0-m.png``, ``000007.0-o.png`` with ``opacity_output``, ..., ``000007.gt.png``,
``000007.cameras.json``) and ``000007.homographies.npy`` (all ``(V, V, 3, 3)`` float64), so
``webdataset.WebDataset("out/shard-{00000..00009}.tar")`` reads them too. Entries have mode 644
and time 0: equal data gives equal tars.
"""

from __future__ import annotations

import io
import tarfile
from contextlib import nullcontext
from pathlib import Path
from typing import Any, Callable, Iterator

import numpy as np

from ..sample import SampleArrays
from .layout import SHARD_NAME, TMP_PREFIX, encode, sample_entries, sequence_name

HOMOGRAPHIES = "homographies.npy"


def entries(arrays: SampleArrays) -> dict[str, Any]:
    """A sequence's entries by name (without the key): the shared entries, then ``homographies.npy``."""
    return {**sample_entries(arrays), HOMOGRAPHIES: arrays.homographies}


def shard_path(out: Path, shard: int) -> Path:
    return out / f"shard-{shard:05d}.tar"


def shard_contents(path: Path) -> dict[int, list[tarfile.TarInfo]]:
    """``{index: [member, ...]}`` of the shard at ``path`` (empty if there is none)."""
    if not path.exists():
        return {}
    contents: dict[int, list[tarfile.TarInfo]] = {}
    with tarfile.open(path) as tar:
        for member in tar.getmembers():
            contents.setdefault(int(member.name.partition(".")[0]), []).append(member)
    return contents


def present(out: Path, wanted: range, shard_size: int) -> set[int]:
    """The indices of ``wanted`` (non-empty) that the shards in ``out`` hold."""
    shards = range(wanted.start // shard_size, (wanted.stop - 1) // shard_size + 1)
    return {i for k in shards for i in shard_contents(shard_path(out, k)) if i in wanted}


def write_shard(out: Path, shard: int, new: list[int], arrays: Iterator[SampleArrays],
                written: Callable[[], None]) -> None:
    """(Re)write one shard: the sequences it holds copied over, those of ``new`` (ascending) taken
    from ``arrays``, all in index order, into ``.tmp-shard-<k>.tar``, then moved into place;
    ``written()`` is called after each new sequence."""
    path = shard_path(out, shard)
    old = shard_contents(path)
    tmp = out / (TMP_PREFIX + path.name)
    try:
        with tarfile.open(tmp, "w") as tar, (open(path, "rb") if old else nullcontext()) as old_file:
            for index in sorted({*old, *new}):
                if index in old:
                    for member in old[index]:
                        old_file.seek(member.offset_data)
                        _add_entry(tar, member.name, old_file.read(member.size))
                    continue
                sample = next(arrays)
                if sample.index != index:
                    raise RuntimeError(f"internal: shard {shard} expected sequence {index}, got {sample.index}")
                for name, data in encode(entries(sample)).items():
                    _add_entry(tar, f"{sequence_name(index)}.{name}", data)
                written()
        tmp.replace(path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def _add_entry(tar: tarfile.TarFile, name: str, data: bytes) -> None:
    """Add file ``name`` holding ``data`` to ``tar`` (mode 644, time 0: equal data, equal tars)."""
    info = tarfile.TarInfo(name)
    info.size, info.mode, info.mtime = len(data), 0o644, 0
    tar.addfile(info, io.BytesIO(data))


def sequences(out: Path) -> list[tuple[int, dict[str, tuple[Path, int, int]]]]:
    """``(index, {entry name: (shard, offset, size)})`` of every sequence in the shards of ``out``, ascending."""
    items = []
    for shard in sorted(p for p in out.iterdir() if SHARD_NAME.match(p.name)):
        for index, members in sorted(shard_contents(shard).items()):
            items.append((index, {m.name.partition(".")[2]: (shard, m.offset_data, m.size) for m in members}))
    return items


def read_entry(entries: dict[str, tuple[Path, int, int]], name: str) -> bytes:
    """The bytes of entry ``name`` of one sequence (``FileNotFoundError`` naming it if missing)."""
    if name not in entries:
        raise FileNotFoundError(f"shard entry {name!r} missing (entries: {sorted(entries)})")
    shard, offset, size = entries[name]
    with open(shard, "rb") as f:
        f.seek(offset)
        return f.read(size)


def read_homographies(read: Callable[[str], Any], n_views: int) -> np.ndarray:
    """``(V, V, 3, 3)`` float64 from the ``homographies.npy`` entry."""
    return read(HOMOGRAPHIES)
