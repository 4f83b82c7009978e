"""Export: freeze a :class:`~sidar_torch.SidarDataset` to disk, and read it back.

:func:`export_dataset` writes sequences ``start .. start + count - 1`` of a dataset in the SIDAR
paper's file layout (the default) or in WebDataset-style tar shards; :class:`ExportedDataset`
loads either back into the dict :meth:`SidarDataset.sample` returns, tensor for tensor
byte-identical (the views are 8-bit renders, so 8-bit PNGs hold them exactly).

Folder layout (``shards=None``)::

    out/
      export.json        format, package version, layout, seed, painting source, config
      config.yaml        the config (``load_config("out/config.yaml")`` gives it back)
      000000/            one folder per sequence, named by its dataset index (at least 6 digits)
        0.png .. <V-1>.png   the views, 8-bit RGB; view 0 is the reference camera
        0-m.png ..           the masks, 8-bit grey: 255 where the painting is not visible, else 0
        0-o.png ..           only with ``opacity_output``: the opacities, 8-bit grey, 255 times
                             the fraction of the painting hidden (exact: they are multiples of 1/255)
        gt.png               the label (the painting in view 0's frame, unlit, unoccluded)
        H_<i>_<j>.mat        homographies[i, j] for every ordered pair i != j: a MATLAB file
                             with one variable ``H``, 3 x 3 float64 (det = 1)
        cameras.json         index, image_size [H, W], K, R, t per view (float64), homography_error

The paper writes one file per unordered pair; both directions are written here so that
``H[j, i]`` is the dataset's own fit (within float64 round-off of ``inv(H[i, j])``, not equal
to it bit for bit). ``H[i, i]`` is the identity and not written.

Shard layout (``shards=N``): ``shard-00000.tar``, ``shard-00001.tar``, ...; shard ``k`` holds the
exported sequences with indices in ``[k N, (k + 1) N)``, in index order. Entries follow WebDataset's
naming, ``<key>.<name>`` with ``key`` the 6-digit index: ``000007.0.png``, ``000007.0-m.png``,
(``000007.0-o.png`` with ``opacity_output``),
``000007.gt.png``, ``000007.homographies.npy`` (all ``(V, V, 3, 3)`` float64) and
``000007.cameras.json``, so ``webdataset.WebDataset("out/shard-{00000..00009}.tar")`` reads them too.

Homography convention: the package's (Kornia's): pixel ``(u, v)`` is column ``u``, row ``v``, the
centre of the top-left pixel is ``(0, 0)``, and ``H[i, j]`` maps view-i pixels to view-j pixels.
The paper's Blender files use coordinates in which the image's outer edges are ``0`` and
``W - 1`` (``x = (u + 1/2) (W - 1) / W``, likewise for rows), up to half a pixel off the rendered
pixel grid; to compare with them, conjugate: ``H_paper = S H S^-1`` with
``S = [[(W-1)/W, 0, (W-1)/(2W)], [0, (H-1)/H, (H-1)/(2H)], [0, 0, 1]]``.

Safety. Each sequence (or shard) is written into ``out/.tmp-<name>`` and moved into place by one
``os.replace``, so a folder ``000007/`` or a ``shard-*.tar`` is either complete or absent. A
rerun with the same arguments skips what exists, deletes stale ``.tmp-*`` left by a killed run
and renders only what is missing; samples are pure functions of ``(seed, index)``, so the result
is byte for byte an uninterrupted export's. Files are not ``fsync``-ed: this protects against
the process dying (exception, Ctrl-C, ``kill -9``), not against losing power. One export at a
time may write to a folder (an ``flock`` on ``out/.export.lock``), and a rerun must keep the
seed, source, config and layout recorded in ``export.json`` (else ``ValueError``).
"""

from __future__ import annotations

import dataclasses
import fcntl
import hashlib
import io
import itertools
import json
import os
import re
import shutil
import sys
import tarfile
import time
from contextlib import contextmanager, nullcontext
from functools import partial
from pathlib import Path
from typing import Any, Iterator, Mapping, TextIO

import numpy as np
import scipy.io
import torch
import yaml
from PIL import Image
from torch.utils.data import DataLoader, Dataset

from .dataset import SidarDataset, _check_int, sequence_homographies
from .sources import ImageFiles, PaintingSource

__all__ = ["ExportSummary", "ExportedDataset", "export_dataset"]

FORMAT = "sidar_torch export"
FORMAT_VERSION = 1
MANIFEST = "export.json"
LOCK = ".export.lock"
TMP_PREFIX = ".tmp-"
SEQUENCE_NAME = re.compile(r"^\d{6,}$")
SHARD_NAME = re.compile(r"^shard-(\d{5,})\.tar$")
MAT_HEADER = b"MATLAB 5.0 MAT-file, written by sidar_torch"
"""Replaces scipy's header text, which holds the time of writing, so equal data gives equal files."""

_RESUME_KEYS = ("format", "format_version", "package_version", "layout", "shard_size", "seed", "source", "config")
"""``export.json`` fields a rerun into an existing export must match."""


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


@dataclasses.dataclass(frozen=True)
class _Record:
    """One sequence ready to write: ``V`` views of ``H x W`` pixels.

    Attributes:
        index: the dataset index.
        views: ``(V, H, W, 3)`` uint8; masks: ``(V, H, W)`` uint8, 255 where the painting is not
            visible; label: ``(H, W, 3)`` uint8.
        opacities: ``(V, H, W)`` uint8, 255 times the fraction of the painting hidden, or None
            (not rendered).
        homographies: ``(V, V, 3, 3)`` float64; K, R: ``(V, 3, 3)``, t: ``(V, 3)`` float64.
        homography_error: pixels (see :class:`SidarDataset`).
    """

    index: int
    views: np.ndarray
    masks: np.ndarray
    label: np.ndarray
    homographies: np.ndarray
    K: np.ndarray
    R: np.ndarray
    t: np.ndarray
    homography_error: float
    opacities: np.ndarray | None = None


# --------------------------------------------------------------------------- export


def export_dataset(dataset: SidarDataset, out_dir: str | os.PathLike, count: int, start: int = 0,
                   shards: int | None = None, workers: int = 0, progress: bool = True) -> ExportSummary:
    """Write sequences ``start .. start + count - 1`` of ``dataset`` to ``out_dir`` (see the module docstring).

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
            export whose seed, source, config, layout or version differ; a sample's images are not
            8-bit values (``k / 255``) or its masks not in {0, 1}; likewise its opacities.
        RuntimeError: another export holds the lock on ``out_dir``.
    """
    begin = time.perf_counter()
    if not isinstance(dataset, SidarDataset):
        raise TypeError(f"dataset: expected a SidarDataset, got {type(dataset).__name__}")
    count, start = _check_int("count", count, 1), _check_int("start", start, 0)
    shard_size = None if shards is None else _check_int("shards", shards, 1)
    workers = _check_int("workers", workers, 0)
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise NotADirectoryError(f"out_dir: {str(out)!r} exists and is not a folder")
    out.mkdir(parents=True, exist_ok=True)
    with _locked(out):
        _write_manifest(out, dataset, shard_size)
        for stale in out.glob(TMP_PREFIX + "*"):  # left by a killed run; the lock says no one is writing them
            if stale.is_dir():
                shutil.rmtree(stale)
            else:
                stale.unlink()
        wanted = range(start, start + count)
        if shard_size is None:
            present = {int(p.name) for p in out.iterdir() if SEQUENCE_NAME.match(p.name) and int(p.name) in wanted}
        else:
            shards_wanted = range(start // shard_size, (start + count - 1) // shard_size + 1)
            present = {i for k in shards_wanted for i in _shard_contents(_shard_path(out, k)) if i in wanted}
        missing = [i for i in wanted if i not in present]
        bar = _Progress(len(missing), sys.stderr if progress else None)
        records = _render(dataset, missing, workers)
        if shard_size is None:
            for record in records:
                _write_sequence(out, record)
                bar.advance()
        else:
            for shard, new in itertools.groupby(missing, key=lambda i: i // shard_size):
                _write_shard(out, shard, list(new), records, bar)
        bar.close()
    return ExportSummary(out, tuple(missing), len(present), time.perf_counter() - begin)


@contextmanager
def _locked(out: Path) -> Iterator[None]:
    """Hold an exclusive ``flock`` on ``out/.export.lock`` (released when the process dies)."""
    with open(out / LOCK, "a") as lock:
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise RuntimeError(f"out_dir: another export is writing to {str(out)!r} "
                               f"(it holds the lock on {str(out / LOCK)!r})") from None
        try:
            yield
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)


def _source_description(source: PaintingSource) -> dict[str, Any]:
    """Plain-data description of a painting source: its kind, size, crop and, for files, their paths' hash."""
    description: dict[str, Any] = {"type": type(source).__name__, "paintings": len(source)}
    if hasattr(source, "crop"):
        description["crop"] = source.crop
    if isinstance(source, ImageFiles):
        description["first_path"] = source.paths[0]
        description["paths_sha256"] = hashlib.sha256("\n".join(source.paths).encode()).hexdigest()
    return description


def _write_manifest(out: Path, dataset: SidarDataset, shard_size: int | None) -> None:
    """Write ``export.json`` and ``config.yaml``, or check that a rerun matches the existing ones."""
    from . import __version__

    manifest = {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "package_version": __version__,
        "layout": "folders" if shard_size is None else "shards",
        "shard_size": shard_size,
        "seed": dataset.seed,
        "source": _source_description(dataset.source),
        "config": dataset.config.to_dict(),
        "homographies": "H[i, j] maps view-i pixels to view-j pixels; Kornia pixels (centre of the top-left "
                        "pixel at (0, 0)); det = 1; float64",
        "masks": "255 where the painting is not visible (occluder or background), 0 where it is",
    }
    if dataset.config.opacity_output:
        manifest["opacities"] = "<i>-o.png: 255 x the fraction of the painting hidden (1 off the painting)"
    path = out / MANIFEST
    if path.exists():
        old = _read_manifest(out)
        differences = [_difference(key, old.get(key), manifest[key]) for key in _RESUME_KEYS
                       if old.get(key) != manifest[key]]
        if differences:
            raise ValueError(f"out_dir: {str(out)!r} holds an export made with other settings "
                             f"({'; '.join(differences)}); export into a new folder or rerun with the recorded ones")
        return
    foreign = sorted(p.name for p in out.iterdir() if p.name != LOCK and not p.name.startswith(TMP_PREFIX))
    if foreign:
        raise ValueError(f"out_dir: {str(out)!r} is not empty and holds no {MANIFEST} (found {foreign[:5]}); "
                         f"export into a new or empty folder")
    _replace_file(out / "config.yaml", yaml.safe_dump(manifest["config"], sort_keys=False).encode())
    _replace_file(path, (json.dumps(manifest, indent=2) + "\n").encode())


def _difference(key: str, there: Any, now: Any) -> str:
    """``"key: <there> there, <now> now"``, naming only the differing fields of two dicts."""
    if isinstance(there, dict) and isinstance(now, dict):
        fields = sorted(k for k in {*there, *now} if there.get(k, "(absent)") != now.get(k, "(absent)"))
        return "; ".join(f"{key}.{k}: {there.get(k, '(absent)')!r} there, {now.get(k, '(absent)')!r} now"
                         for k in fields)
    return f"{key}: {there!r} there, {now!r} now"


def _replace_file(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically (a temporary sibling, then ``os.replace``)."""
    tmp = path.with_name(TMP_PREFIX + path.name)
    _write_file(tmp, data)
    os.replace(tmp, path)


def _write_file(path: Path, data: bytes) -> None:
    """Write one file (the single place export writes file contents)."""
    with open(path, "wb") as f:
        f.write(data)


def _sequence_name(index: int) -> str:
    return f"{index:06d}"


class _Renders(Dataset):
    """Map-style view of the indices to render: item ``k`` is the :class:`_Record` of ``indices[k]``."""

    def __init__(self, dataset: SidarDataset, indices: list[int]):
        self.dataset, self.indices = dataset, indices

    def __len__(self) -> int:
        return len(self.indices)

    def __getitem__(self, k: int) -> _Record:
        return _record(self.dataset, self.indices[k])


def _keep(item: Any) -> Any:
    """DataLoader ``collate_fn`` that hands items over unchanged (picklable, unlike a lambda)."""
    return item


def _render(dataset: SidarDataset, indices: list[int], workers: int) -> Iterator[_Record]:
    """The records of ``indices``, in order, rendered here (``workers=0``) or in DataLoader workers."""
    if workers == 0 or not indices:
        return (_record(dataset, index) for index in indices)
    return iter(DataLoader(_Renders(dataset, indices), batch_size=None, num_workers=workers, collate_fn=_keep))


def _record(dataset: SidarDataset, index: int) -> _Record:
    """Render sample ``index`` and convert it for writing: 8-bit pixels, float64 geometry."""
    sample = dataset.sample(index)
    sequence = dataset.scene(index)
    homographies = sequence_homographies(sequence)[0]
    if not torch.equal(homographies.float(), sample["homographies"]):
        raise RuntimeError(f"sample {index}: its homographies differ from those of its scene "
                           f"(dataset.sample and dataset.scene disagree)")
    K, R, t = sequence.cameras()
    masks = sample["masks"][:, 0]
    if not bool(((masks == 0) | (masks == 1)).all()):
        raise ValueError(f"sample {index}: masks: expected values in {{0, 1}}")
    opacities = _to_uint8(sample["opacities"][:, 0], "opacities", index) if "opacities" in sample else None
    return _Record(index, _to_uint8(sample["images"].permute(0, 2, 3, 1), "images", index),
                   masks.to(torch.uint8).mul_(255).numpy(), _to_uint8(sample["label"].permute(1, 2, 0), "label", index),
                   homographies.numpy(), K, R, t, float(sample["homography_error"]), opacities)


def _to_uint8(values: torch.Tensor, name: str, index: int) -> np.ndarray:
    """Float values ``k / 255`` -> uint8 ``k``; anything else would not survive a PNG, so it raises."""
    quantised = values.mul(255).round_().clamp_(0, 255).to(torch.uint8)
    if not torch.equal(quantised.float().div_(255), values):
        raise ValueError(f"sample {index}: {name}: expected 8-bit values k / 255 (what the renderer produces); "
                         f"8-bit PNGs would change them")
    return quantised.contiguous().numpy()


def _png(pixels: np.ndarray) -> bytes:
    buffer = io.BytesIO()
    Image.fromarray(pixels).save(buffer, format="PNG")
    return buffer.getvalue()


def _mat(H: np.ndarray) -> bytes:
    """A MATLAB 5 file with variable ``H`` (3 x 3 float64), with a fixed header text."""
    buffer = io.BytesIO()
    scipy.io.savemat(buffer, {"H": np.ascontiguousarray(H, dtype=np.float64)})
    data = buffer.getvalue()
    return MAT_HEADER.ljust(116) + data[116:]  # the format's first 116 bytes are free text


def _npy(array: np.ndarray) -> bytes:
    buffer = io.BytesIO()
    np.save(buffer, array)
    return buffer.getvalue()


def _cameras_json(record: _Record) -> bytes:
    data = {
        "index": record.index,
        "image_size": list(record.label.shape[:2]),
        "K": record.K.tolist(),
        "R": record.R.tolist(),
        "t": record.t.tolist(),
        "homography_error": record.homography_error,
        "frame": "OpenCV camera frame (x right, y down, z forward): world point X lands at K (R X + t); "
                 "K in pixels, Kornia pixel centres",
    }
    return (json.dumps(data, indent=1) + "\n").encode()


def _pixel_files(record: _Record) -> dict[str, bytes]:
    """The files both layouts share, by name: views, masks, opacities (if rendered), label, cameras."""
    files = {}
    for v in range(len(record.views)):
        files[f"{v}.png"] = _png(record.views[v])
        files[f"{v}-m.png"] = _png(record.masks[v])
        if record.opacities is not None:
            files[f"{v}-o.png"] = _png(record.opacities[v])
    files["gt.png"] = _png(record.label)
    files["cameras.json"] = _cameras_json(record)
    return files


def _write_sequence(out: Path, record: _Record) -> None:
    """Write one sequence folder into ``.tmp-<name>``, then move it into place in one step."""
    files = _pixel_files(record)
    for i, j in itertools.permutations(range(len(record.views)), 2):
        files[f"H_{i}_{j}.mat"] = _mat(record.homographies[i, j])
    name = _sequence_name(record.index)
    tmp = out / (TMP_PREFIX + name)
    tmp.mkdir()
    try:
        for file_name, data in files.items():
            _write_file(tmp / file_name, data)
        os.replace(tmp, out / name)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def _shard_path(out: Path, shard: int) -> Path:
    return out / f"shard-{shard:05d}.tar"


def _shard_contents(path: Path) -> dict[int, list[tarfile.TarInfo]]:
    """``{index: [member, ...]}`` of the shard at ``path`` (empty if there is none)."""
    if not path.exists():
        return {}
    contents: dict[int, list[tarfile.TarInfo]] = {}
    with tarfile.open(path) as tar:
        for member in tar.getmembers():
            contents.setdefault(int(member.name.partition(".")[0]), []).append(member)
    return contents


def _write_shard(out: Path, shard: int, new: list[int], records: Iterator[_Record], bar: "_Progress") -> None:
    """(Re)write one shard: the sequences it holds copied over, those of ``new`` (ascending) taken
    from ``records``, all in index order, into ``.tmp-shard-<k>.tar``, then moved into place."""
    path = _shard_path(out, shard)
    old = _shard_contents(path)
    tmp = out / (TMP_PREFIX + path.name)
    try:
        with tarfile.open(tmp, "w") as tar, (open(path, "rb") if old else nullcontext()) as old_file:
            for index in sorted({*old, *new}):
                if index in old:
                    for member in old[index]:
                        old_file.seek(member.offset_data)
                        _add_entry(tar, member.name, old_file.read(member.size))
                    continue
                record = next(records)
                if record.index != index:
                    raise RuntimeError(f"internal: shard {shard} expected sequence {index}, got {record.index}")
                entries = _pixel_files(record)
                entries["homographies.npy"] = _npy(record.homographies)
                for name, data in entries.items():
                    _add_entry(tar, f"{_sequence_name(index)}.{name}", data)
                bar.advance()
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def _add_entry(tar: tarfile.TarFile, name: str, data: bytes) -> None:
    """Add file ``name`` holding ``data`` to ``tar`` (mode 644, time 0: equal data, equal tars)."""
    info = tarfile.TarInfo(name)
    info.size, info.mode, info.mtime = len(data), 0o644, 0
    tar.addfile(info, io.BytesIO(data))


class _Progress:
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


# --------------------------------------------------------------------------- reading


def _read_manifest(path: Path) -> dict[str, Any]:
    manifest_path = path / MANIFEST
    if not manifest_path.is_file():
        raise ValueError(f"{str(path)!r}: not a sidar_torch export (no {MANIFEST})")
    try:
        manifest = json.loads(manifest_path.read_text())
    except json.JSONDecodeError as error:
        raise ValueError(f"{str(manifest_path)!r}: not valid JSON ({error})") from None
    if manifest.get("format") != FORMAT or manifest.get("format_version") != FORMAT_VERSION:
        raise ValueError(f"{str(manifest_path)!r}: expected format {FORMAT!r} version {FORMAT_VERSION}, "
                         f"got {manifest.get('format')!r} version {manifest.get('format_version')!r}")
    return manifest


class ExportedDataset(Dataset):
    """A set written by :func:`export_dataset`, read back as :class:`SidarDataset` samples.

    A map-style dataset: item ``k`` is the ``k``-th exported sequence in index order (``indices[k]``
    is its dataset index), as the dict :meth:`SidarDataset.sample` returns, with the same keys,
    shapes and dtypes and, for the same seed, config and source, the same values bit for bit:
    ``images`` ``(V, 3, H, W)``, ``masks`` ``(V, 1, H, W)``, ``opacities`` ``(V, 1, H, W)`` (only
    if the set was rendered with ``opacity_output``), ``label`` ``(3, H, W)``,
    ``homographies`` ``(V, V, 3, 3)``, ``K``, ``R`` ``(V, 3, 3)``, ``t`` ``(V, 3)`` float32,
    ``homography_error`` float, ``index`` int. Reads both layouts; works in DataLoader workers.

    Args:
        path: the export folder.

    Attributes:
        config: the config fields the set was rendered with, as recorded (a dict, so that sets
            written by other versions of the package load; ``SidarConfig(**config)`` rebuilds it
            when the fields match this version's).
        seed: its seed.
        layout: ``"folders"`` or ``"shards"``.
        indices: dataset index of each item, ascending.

    Raises:
        FileNotFoundError: ``path`` does not exist.
        ValueError: ``path`` holds no export (no ``export.json``) or one of another format.
    """

    def __init__(self, path: str | os.PathLike):
        self.path = Path(path)
        if not self.path.is_dir():
            raise FileNotFoundError(f"path: no export folder at {str(self.path)!r}")
        manifest = _read_manifest(self.path)
        self.config: dict[str, Any] = manifest["config"]
        self.seed: int = manifest["seed"]
        self.layout: str = manifest["layout"]
        # Per item: its index and where its entries are: a folder, or {name: (shard, offset, size)}.
        self._items: list[tuple[int, Path | dict[str, tuple[Path, int, int]]]] = []
        if self.layout == "folders":
            names = [p.name for p in self.path.iterdir() if p.is_dir() and SEQUENCE_NAME.match(p.name)]
            self._items = [(int(name), self.path / name) for name in sorted(names, key=int)]
        else:
            for shard in sorted(p for p in self.path.iterdir() if SHARD_NAME.match(p.name)):
                for index, members in sorted(_shard_contents(shard).items()):
                    entries = {m.name.partition(".")[2]: (shard, m.offset_data, m.size) for m in members}
                    self._items.append((index, entries))
        self.indices = [index for index, _ in self._items]

    def __len__(self) -> int:
        return len(self._items)

    def __getitem__(self, k: int) -> dict[str, Any]:
        """Item ``k`` (``0 <= k < len(self)``, negative counts from the end) as a sample dict."""
        if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or not -len(self) <= k < len(self):
            raise IndexError(f"index {k!r}: expected an integer in [{-len(self)}, {len(self)})")
        index, where = self._items[k]
        read = partial(_read_file, where) if isinstance(where, Path) else partial(_read_entry, where)
        cameras = json.loads(read("cameras.json"))
        n_views = len(cameras["K"])
        if isinstance(where, Path):
            homographies = np.zeros((n_views, n_views, 3, 3))
            homographies[np.arange(n_views), np.arange(n_views)] = np.eye(3)
            for i, j in itertools.permutations(range(n_views), 2):
                homographies[i, j] = scipy.io.loadmat(io.BytesIO(read(f"H_{i}_{j}.mat")))["H"]
        else:
            homographies = np.load(io.BytesIO(read("homographies.npy")))
        views = np.stack([_read_png(read(f"{v}.png")) for v in range(n_views)])
        masks = np.stack([_read_png(read(f"{v}-m.png")) for v in range(n_views)])
        label = _read_png(read("gt.png"))
        opacities = {}
        if self.config.get("opacity_output", False):
            hidden = np.stack([_read_png(read(f"{v}-o.png")) for v in range(n_views)])
            opacities["opacities"] = torch.from_numpy(hidden).unsqueeze(1).float().div_(255)
        return {
            "images": torch.from_numpy(views).permute(0, 3, 1, 2).float().div_(255),
            "masks": torch.from_numpy(masks >= 128).unsqueeze(1).float(),
            **opacities,
            "label": torch.from_numpy(label).permute(2, 0, 1).float().div_(255),
            "homographies": torch.from_numpy(homographies).float(),
            "homography_error": float(cameras["homography_error"]),
            "K": torch.tensor(cameras["K"], dtype=torch.float64).float(),
            "R": torch.tensor(cameras["R"], dtype=torch.float64).float(),
            "t": torch.tensor(cameras["t"], dtype=torch.float64).float(),
            "index": index,
        }


def _read_file(folder: Path, name: str) -> bytes:
    return (folder / name).read_bytes()


def _read_entry(entries: Mapping[str, tuple[Path, int, int]], name: str) -> bytes:
    if name not in entries:
        raise FileNotFoundError(f"shard entry {name!r} missing (entries: {sorted(entries)})")
    shard, offset, size = entries[name]
    with open(shard, "rb") as f:
        f.seek(offset)
        return f.read(size)


def _read_png(data: bytes) -> np.ndarray:
    with Image.open(io.BytesIO(data)) as image:
        return np.array(image)
