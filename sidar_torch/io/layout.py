"""What the two export layouts share: names, the manifest, the codecs, atomic writes and the lock.

A sequence is written as named entries (``0.png``, ``gt.png``, ``cameras.json``, ...): the
writers (:mod:`.folders`, :mod:`.shards`) name them, :data:`ENCODERS` turns each into bytes by its
extension and :data:`DECODERS` reads it back. The pixel entries come from the sample table
(:data:`sidar_torch.sample.KEYS`, column ``entry``), so a new 8-bit output is exported and read
back without a change here.
"""

from __future__ import annotations

import fcntl
import hashlib
import io
import json
import os
import re
import shutil
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Callable, Iterator

import numpy as np
import scipy.io
import yaml
from PIL import Image

from ..sample import KEYS, SampleArrays, present_keys
from ..sources import ImageFiles, PaintingSource

FORMAT = "sidar_torch export"
FORMAT_VERSION = 1
MANIFEST = "export.json"
LOCK = ".export.lock"
TMP_PREFIX = ".tmp-"
SEQUENCE_NAME = re.compile(r"^\d{6,}$")
SHARD_NAME = re.compile(r"^shard-(\d{5,})\.tar$")
CAMERAS = "cameras.json"
MAT_HEADER = b"MATLAB 5.0 MAT-file, written by sidar_torch"
"""Replaces scipy's header text, which holds the time of writing, so equal data gives equal files."""

RESUME_KEYS = ("format", "format_version", "package_version", "layout", "shard_size", "seed", "source", "config")
"""``export.json`` fields a rerun into an existing export must match."""


def sequence_name(index: int) -> str:
    """The name of sequence ``index``: its 6-digit (or longer) index."""
    return f"{index:06d}"


# --------------------------------------------------------------------------- codecs


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


def _json(data: dict[str, Any]) -> bytes:
    return (json.dumps(data, indent=1) + "\n").encode()


def _read_png(data: bytes) -> np.ndarray:
    with Image.open(io.BytesIO(data)) as image:
        return np.array(image)


ENCODERS: dict[str, Callable[[Any], bytes]] = {".png": _png, ".mat": _mat, ".npy": _npy, ".json": _json}
"""Entry extension -> encoder: ``.png`` uint8 ``(H, W)`` or ``(H, W, 3)``, ``.mat`` a 3 x 3 float64
``H``, ``.npy`` any array, ``.json`` a dict."""

DECODERS: dict[str, Callable[[bytes], Any]] = {
    ".png": _read_png, ".mat": lambda data: scipy.io.loadmat(io.BytesIO(data))["H"],
    ".npy": lambda data: np.load(io.BytesIO(data)), ".json": json.loads,
}
"""Entry extension -> decoder, the inverse of :data:`ENCODERS`."""


def encode(entries: dict[str, Any]) -> dict[str, bytes]:
    """``{name: value}`` -> ``{name: bytes}``, each by its name's extension."""
    return {name: ENCODERS[os.path.splitext(name)[1]](value) for name, value in entries.items()}


def decode(name: str, data: bytes) -> Any:
    return DECODERS[os.path.splitext(name)[1]](data)


# --------------------------------------------------------------------------- sequences as entries


def sample_entries(arrays: SampleArrays) -> dict[str, Any]:
    """The entries both layouts share, in writing order: per view the 8-bit pixel keys of the
    sample table (``0.png``, ``0-m.png``, ``0-o.png`` if rendered, ...), then the whole-image ones
    (``gt.png``), then ``cameras.json`` (index, image size, K, R, t, homography error)."""
    n_views = len(arrays.images)
    pixel_keys = [key for key in KEYS if key.entry is not None and getattr(arrays, key.name) is not None]
    entries = {key.entry.format(v=v): getattr(arrays, key.name)[v]
               for v in range(n_views) for key in pixel_keys if "{v}" in key.entry}
    entries.update({key.entry: getattr(arrays, key.name) for key in pixel_keys if "{v}" not in key.entry})
    entries[CAMERAS] = {
        "index": arrays.index,
        "image_size": list(arrays.label.shape[:2]),
        "K": arrays.K.tolist(),
        "R": arrays.R.tolist(),
        "t": arrays.t.tolist(),
        "homography_error": arrays.homography_error,
        "frame": "OpenCV camera frame (x right, y down, z forward): world point X lands at K (R X + t); "
                 "K in pixels, Kornia pixel centres",
    }
    return entries


def pixel_entries_text() -> str:
    """The 8-bit pixel files of a sequence, for help texts: ``"<i>.png (images), <i>-m.png (masks), ..."``."""
    return ", ".join(f"{key.entry.format(v='<i>')} ({key.name}{', with ' + key.switch if key.switch else ''})"
                     for key in KEYS if key.entry is not None)


def sample_from_entries(read: Callable[[str], Any], index: int, config: dict[str, Any],
                        homographies: Callable[[int], np.ndarray]) -> SampleArrays:
    """Rebuild the :class:`SampleArrays` of sequence ``index`` from its decoded entries.

    Args:
        read: entry name -> decoded value (raises ``FileNotFoundError`` naming a missing entry).
        index: the sequence's dataset index.
        config: the recorded config (says which keys are present, e.g. ``opacities``).
        homographies: ``V`` -> the ``(V, V, 3, 3)`` float64 homographies, read the layout's way.
    """
    cameras = read(CAMERAS)
    n_views = len(cameras["K"])
    pixels = {}
    for key in present_keys(config):
        if key.entry is None:
            continue
        if "{v}" not in key.entry:
            pixels[key.name] = read(key.entry)
            continue
        views = [read(key.entry.format(v=v)) for v in range(n_views)]
        shapes = sorted({view.shape for view in views})
        if len(shapes) > 1:
            raise ValueError(f"SampleArrays.{key.name}: the files {key.entry.format(v='<v>')} of sequence {index} "
                             f"differ in shape: {shapes}")
        pixels[key.name] = np.stack(views)
    return SampleArrays(**pixels, homographies=homographies(n_views),
                        homography_error=float(cameras["homography_error"]),
                        K=np.array(cameras["K"], dtype=np.float64), R=np.array(cameras["R"], dtype=np.float64),
                        t=np.array(cameras["t"], dtype=np.float64), index=index)


# --------------------------------------------------------------------------- files, atomically


def write_file(path: Path, data: bytes) -> None:
    """Write one file (the single place export writes file contents)."""
    with open(path, "wb") as f:
        f.write(data)


def replace_file(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically (a temporary sibling, then ``os.replace``)."""
    tmp = path.with_name(TMP_PREFIX + path.name)
    write_file(tmp, data)
    os.replace(tmp, path)


def replace_folder(path: Path, files: dict[str, bytes]) -> None:
    """Write ``files`` into ``.tmp-<name>`` beside ``path``, then move it into place in one step."""
    tmp = path.with_name(TMP_PREFIX + path.name)
    tmp.mkdir()
    try:
        for file_name, data in files.items():
            write_file(tmp / file_name, data)
        os.replace(tmp, path)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def remove_stale(out: Path) -> None:
    """Delete the ``.tmp-*`` left by a killed run (call it holding the lock: no one writes them)."""
    for stale in out.glob(TMP_PREFIX + "*"):
        if stale.is_dir():
            shutil.rmtree(stale)
        else:
            stale.unlink()


@contextmanager
def locked(out: Path) -> Iterator[None]:
    """Hold an exclusive lock on ``out/.export.lock`` while writing; the file is removed afterwards.

    A POSIX record lock (``fcntl.lockf``), not ``flock``: it belongs to this process alone, so
    forked DataLoader workers do not inherit it and cannot keep it after this process dies (with
    ``flock`` they did, and a rerun after ``kill -9`` was refused for good); the kernel releases it
    when this process dies, however it dies. The file is removed on the way out, also when the
    export is refused, so no run leaves it behind.

    Raises:
        RuntimeError: another live process holds the lock.
    """
    path = out / LOCK
    fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
    try:
        try:
            fcntl.lockf(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except (BlockingIOError, PermissionError):
            raise RuntimeError(f"out_dir: another export is writing to {str(out)!r} "
                               f"(it holds the lock on {str(path)!r})") from None
        if not path.exists() or os.stat(path).st_ino != os.fstat(fd).st_ino:
            # The holder we waited behind removed the file we locked: another run may hold a new one.
            raise RuntimeError(f"out_dir: another export was finishing in {str(out)!r}; run again")
        try:
            yield
        finally:
            path.unlink(missing_ok=True)  # while holding the lock; a run that opened it meanwhile sees it gone
    finally:
        os.close(fd)  # releases the lock


# --------------------------------------------------------------------------- manifest


def source_description(source: PaintingSource) -> dict[str, Any]:
    """Plain-data description of a painting source: its kind, size, crop and, for files, their paths' hash."""
    description: dict[str, Any] = {"type": type(source).__name__, "paintings": len(source)}
    if hasattr(source, "crop"):
        description["crop"] = source.crop
    if isinstance(source, ImageFiles):
        description["first_path"] = source.paths[0]
        description["paths_sha256"] = hashlib.sha256("\n".join(source.paths).encode()).hexdigest()
    return description


def write_manifest(out: Path, seed: int, source: PaintingSource, config: dict[str, Any],
                   shard_size: int | None) -> None:
    """Write ``export.json`` and ``config.yaml``, or check that a rerun matches the existing ones."""
    from .. import __version__

    manifest = {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "package_version": __version__,
        "layout": "folders" if shard_size is None else "shards",
        "shard_size": shard_size,
        "seed": seed,
        "source": source_description(source),
        "config": config,
        "homographies": "H[i, j] maps view-i pixels to view-j pixels; Kornia pixels (centre of the top-left "
                        "pixel at (0, 0)); det = 1; float64",
        "masks": "255 where the painting is not visible (occluder or background), 0 where it is",
    }
    if config["opacity_output"]:
        manifest["opacities"] = "<i>-o.png: 255 x the fraction of the painting hidden (1 off the painting)"
    path = out / MANIFEST
    if path.exists():
        old = read_manifest(out)
        differences = [_difference(key, old.get(key), manifest[key]) for key in RESUME_KEYS
                       if old.get(key) != manifest[key]]
        if differences:
            raise ValueError(f"out_dir: {str(out)!r} holds an export made with other settings "
                             f"({'; '.join(differences)}); export into a new folder or rerun with the recorded ones")
        return
    foreign = sorted(p.name for p in out.iterdir() if p.name != LOCK and not p.name.startswith(TMP_PREFIX))
    if foreign:
        raise ValueError(f"out_dir: {str(out)!r} is not empty and holds no {MANIFEST} (found {foreign[:5]}); "
                         f"export into a new or empty folder")
    replace_file(out / "config.yaml", yaml.safe_dump(manifest["config"], sort_keys=False).encode())
    replace_file(path, (json.dumps(manifest, indent=2) + "\n").encode())


def _difference(key: str, there: Any, now: Any) -> str:
    """``"key: <there> there, <now> now"``, naming only the differing fields of two dicts."""
    if isinstance(there, dict) and isinstance(now, dict):
        fields = sorted(k for k in {*there, *now} if there.get(k, "(absent)") != now.get(k, "(absent)"))
        return "; ".join(f"{key}.{k}: {there.get(k, '(absent)')!r} there, {now.get(k, '(absent)')!r} now"
                         for k in fields)
    return f"{key}: {there!r} there, {now!r} now"


def read_manifest(path: Path) -> dict[str, Any]:
    """The ``export.json`` of the export at ``path``, checked to be of this format and version."""
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
