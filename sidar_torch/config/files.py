"""Reading a user's file safely: a regular file only (a FIFO, a device or a folder is refused before
any byte is read, and the file is opened without blocking), and at most a given number of bytes.

Config files (:mod:`.loader`) are read here; the export reader (:mod:`sidar_torch.io.files`) adds
its own check that a file lies inside the export and opens it here too.
"""

from __future__ import annotations

import errno
import os
import stat
from contextlib import contextmanager
from typing import BinaryIO, Iterator

__all__ = ["check_regular", "file_kind", "open_regular", "read_regular"]


def file_kind(mode: int) -> str:
    """What a ``st_mode`` is, in words: ``"folder"``, ``"FIFO"``, ``"character device"``, ..."""
    kinds = ((stat.S_ISDIR, "folder"), (stat.S_ISFIFO, "FIFO"), (stat.S_ISCHR, "character device"),
             (stat.S_ISBLK, "block device"), (stat.S_ISSOCK, "socket"))
    return next((kind for test, kind in kinds if test(mode)), "special file")


def check_regular(path: str | os.PathLike, mode: int, what: str = "") -> None:
    """Refuse a ``st_mode`` that is not a regular file's.

    Args:
        what: how the message names the file (``"config file "``); it ends with ``repr(str(path))``.

    Raises:
        ValueError: ``"<what>'<path>': not a regular file: expected a regular file, got a FIFO"``.
    """
    if not stat.S_ISREG(mode):
        raise ValueError(f"{what}{str(path)!r}: not a regular file: expected a regular file, got a {file_kind(mode)}")


@contextmanager
def open_regular(path: str | os.PathLike, what: str = "") -> Iterator[BinaryIO]:
    """``path`` (links followed) opened for reading in binary, checked to be a regular file before it
    is opened and again once open; opened with ``O_NONBLOCK``, so a FIFO swapped in between the two
    checks does not block the open.

    Raises:
        FileNotFoundError: ``path`` does not exist (the message names it, after ``what``).
        ValueError: as :func:`check_regular`, or ``path`` is a loop of symbolic links.
    """
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        raise FileNotFoundError(f"{what}{str(path)!r} does not exist") from None
    except OSError as error:
        if error.errno != errno.ELOOP:
            raise
        raise ValueError(f"{what}{str(path)!r}: not a regular file: expected a regular file, got a loop of symbolic "
                         f"links (each names the next, none a file)") from None
    check_regular(path, mode, what)
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
    with os.fdopen(fd, "rb") as f:
        check_regular(path, os.fstat(fd).st_mode, what)
        yield f


def read_regular(path: str | os.PathLike, limit: int, what: str = "") -> bytes:
    """The bytes of the regular file ``path`` (see :func:`open_regular`), at most ``limit`` of them.

    Raises:
        FileNotFoundError, ValueError: as :func:`open_regular`; ``ValueError`` too for a file of more
            than ``limit`` bytes (nothing beyond ``limit + 1`` bytes is read).
    """
    with open_regular(path, what) as f:
        data = f.read(limit + 1)
    if len(data) > limit:
        raise ValueError(f"{what}{str(path)!r}: larger than {limit} bytes, the most such a file may hold")
    return data
