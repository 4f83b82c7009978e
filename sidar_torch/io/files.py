"""Files of an export folder: atomic writes under the export's own temporary names, the lock, and
bounded reads of regular files inside the export.

What an export may delete is only what it wrote: temporaries are named ``.tmp-sidar-<name>`` where
``<name>`` is a name the export writes (a sequence folder, a shard, ``export.json``,
``config.yaml``), and the lock file holds :data:`LOCK_MARKER`. Any other file, ``.tmp-*`` or
``.export.lock`` included, is the user's: it is never deleted, and it makes a folder without
``export.json`` "not empty".
"""

from __future__ import annotations

import fcntl
import os
import shutil
from contextlib import contextmanager
from pathlib import Path
from typing import BinaryIO, Iterator

from ..config.files import open_regular
from .layout import is_export_name

TMP_PREFIX = ".tmp-sidar-"
LOCK = ".export.lock"
LOCK_MARKER = b"sidar_torch export lock\n"
"""The lock file's content: a file named ``.export.lock`` without it is not the export's."""


def temporary_path(path: Path) -> Path:
    """Where ``path`` is written before it is moved into place: ``.tmp-sidar-<name>`` beside it."""
    return path.with_name(TMP_PREFIX + path.name)


def is_own_temporary(name: str) -> bool:
    """True for the name of a temporary an export writes (``.tmp-sidar-000007``, ``.tmp-sidar-export.json``)."""
    return name.startswith(TMP_PREFIX) and is_export_name(name[len(TMP_PREFIX):])


def write_file(path: Path, data: bytes) -> None:
    """Write one file (the single place export writes file contents)."""
    with open(path, "wb") as f:
        f.write(data)


def replace_file(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically (its temporary, then ``os.replace``); on any failure
    (a full disk, Ctrl-C) the temporary is removed and ``path`` is as it was."""
    tmp = temporary_path(path)
    try:
        write_file(tmp, data)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def replace_folder(path: Path, files: dict[str, bytes]) -> None:
    """Write ``files`` into the temporary folder of ``path``, then move it into place in one step."""
    tmp = temporary_path(path)
    tmp.mkdir()
    try:
        for file_name, data in files.items():
            write_file(tmp / file_name, data)
        os.replace(tmp, path)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def remove_stale(out: Path) -> None:
    """Delete the export's temporaries left in ``out`` by a killed run, and nothing else (call it
    holding the lock: no one writes them)."""
    for stale in out.iterdir():
        if not is_own_temporary(stale.name):
            continue
        if stale.is_dir() and not stale.is_symlink():
            shutil.rmtree(stale)
        else:
            stale.unlink()


def remove_stale_temporary(path: Path) -> None:
    """Delete the temporary of ``path`` (a sequence folder) left by an attempt that died, if any."""
    shutil.rmtree(temporary_path(path), ignore_errors=True)


@contextmanager
def locked(out: Path) -> Iterator[None]:
    """Hold an exclusive lock on ``out/.export.lock`` while writing; the file is removed afterwards.

    A POSIX record lock (``fcntl.lockf``), not ``flock``: it belongs to this process alone, so
    forked DataLoader workers do not inherit it and cannot keep it after this process dies (with
    ``flock`` they did, and a rerun after ``kill -9`` was refused for good); the kernel releases it
    when this process dies, however it dies. The file holds :data:`LOCK_MARKER`, written as it is
    created: a killed run's lock file is taken over, a ``.export.lock`` of the user's is refused
    and kept. The file is removed on the way out, also when the export is refused.

    Raises:
        RuntimeError: another live process holds the lock.
        ValueError: ``out/.export.lock`` exists and is not an export's lock file.
    """
    path = out / LOCK
    fd, created = _open_lock_file(path)
    try:
        try:
            fcntl.lockf(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except (BlockingIOError, PermissionError):
            raise RuntimeError(f"out_dir: another export is writing to {str(out)!r} "
                               f"(it holds the lock on {str(path)!r})") from None
        if not path.exists() or os.stat(path).st_ino != os.fstat(fd).st_ino:
            # The holder we waited behind removed the file we locked: another run may hold a new one.
            raise RuntimeError(f"out_dir: another export was finishing in {str(out)!r}; run again")
        if not created and os.pread(fd, len(LOCK_MARKER) + 1, 0) != LOCK_MARKER:
            raise ValueError(f"out_dir: {str(path)!r} is not the lock file of a sidar_torch export (it is kept); "
                             f"export into another folder, or move that file away")
        try:
            yield
        finally:
            path.unlink(missing_ok=True)  # while holding the lock; a run that opened it meanwhile sees it gone
    finally:
        os.close(fd)  # releases the lock


def _open_lock_file(path: Path) -> tuple[int, bool]:
    """``(descriptor, created)``: a new lock file holding :data:`LOCK_MARKER`, or the existing one."""
    flags = os.O_RDWR | os.O_CLOEXEC | os.O_NOFOLLOW
    try:
        fd = os.open(path, flags | os.O_CREAT | os.O_EXCL, 0o644)
    except FileExistsError:
        return os.open(path, flags), False
    os.write(fd, LOCK_MARKER)
    return fd, True


@contextmanager
def open_inside(path: Path, root: Path) -> Iterator[BinaryIO]:
    """``path`` opened for reading, checked to be a regular file inside the folder ``root`` (after
    following links): a FIFO, a device or a link out of ``root`` is refused before any byte is read
    (:func:`sidar_torch.config.files.open_regular` opens it).

    Raises:
        FileNotFoundError: ``path`` does not exist.
        ValueError: ``path`` leads outside ``root`` or is not a regular file (the message names it).
    """
    real, base = os.path.realpath(path), os.path.realpath(root)
    if os.path.commonpath([real, base]) != base:
        raise ValueError(f"{str(path)!r}: leads outside the export {str(root)!r} (to {real!r}); "
                         f"an export reads only its own files")
    with open_regular(real) as f:
        yield f


def read_inside(path: Path, root: Path, limit: int) -> bytes:
    """The bytes of the regular file ``path`` inside ``root`` (see :func:`open_inside`), at most ``limit``;
    no more memory is asked for than the file holds (Python reserves what a read asks for).

    Raises:
        FileNotFoundError, ValueError: as :func:`open_inside`; ``ValueError`` too for a file larger
            than ``limit`` bytes, or one that grew while it was read.
    """
    with open_inside(path, root) as f:
        size = os.fstat(f.fileno()).st_size
        data = f.read(min(size, limit) + 1)
    if len(data) > limit:
        raise ValueError(f"{str(path)!r}: larger than {limit} bytes, the most this export's files can hold")
    if len(data) > size:
        raise ValueError(f"{str(path)!r}: grew while it was read (from {size} bytes); read it again once written")
    return data
