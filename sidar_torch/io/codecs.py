"""The bytes of an export's entries, by the entry name's extension: :data:`ENCODERS` turns a value
into bytes, :data:`DECODERS` reads it back (``.png`` 8-bit images, ``.mat`` a homography for MATLAB,
``.npy`` arrays, ``.json`` dicts) from bytes of any origin: a file that is not what its name says
is a ``ValueError``, and every size is checked from its header before anything of that size is
decoded, inflated or allocated. :func:`png_size` reads a PNG's size without decoding it.
"""

from __future__ import annotations

import io
import json
import math
import os
import struct
from contextlib import contextmanager
from typing import Any, Callable, Iterator

import numpy as np
import scipy.io
from PIL import Image

from ..config.numbers import long_integer_text

__all__ = ["DECODERS", "ENCODERS", "MAT_HEADER", "MAT_LIMIT", "decode", "encode", "png_size", "read_json",
           "unreadable"]

MAT_HEADER = b"MATLAB 5.0 MAT-file, written by sidar_torch"
"""Replaces scipy's header text, which holds the time of writing, so equal data gives equal files."""


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


PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
PNG_CHANNEL_AXES = {0: (), 2: (3,)}
"""PNG colour type -> the trailing axes of its pixels, for the kinds :func:`_png` writes (8-bit grey, RGB)."""

MAT_LIMIT = 4096
"""Most bytes of an export's ``.mat`` file: a 3 x 3 float64 ``H`` takes 256 (a compressed one
inflates at most about 1000-fold, so this also bounds what reading a tampered one inflates)."""


def png_size(data: bytes) -> tuple[int, int] | None:
    """``(H, W)`` pixels from the header of the PNG ``data`` (nothing decoded), or None if it is not a PNG."""
    if len(data) < 24 or not data.startswith(PNG_SIGNATURE) or data[12:16] != b"IHDR":
        return None
    width, height = struct.unpack(">II", data[16:24])
    return height, width


@contextmanager
def unreadable(kind: str) -> Iterator[None]:
    """Turn whatever a library raises while decoding hostile bytes into ``ValueError("not a readable
    <kind> (...)")``; a ``MemoryError`` stays one (the callers check every size before decoding)."""
    try:
        yield
    except MemoryError:
        raise
    except Exception as error:
        raise ValueError(f"not a readable {kind} ({type(error).__name__}: {error})") from None


def _read_png(data: bytes, shape: tuple[int, ...] | None = None) -> np.ndarray:
    """``(H, W)`` or ``(H, W, 3)`` uint8 from an 8-bit grey or RGB PNG; with ``shape``, only a PNG
    whose header gives that shape, checked before anything is decoded."""
    if png_size(data) is None:
        raise ValueError(f"not a PNG (no PNG signature and header; starts with {data[:8]!r})")
    depth, colour = data[24:26] if len(data) >= 26 else (None, None)
    if shape is not None:
        if png_size(data) != shape[:2]:
            raise ValueError(f"not a PNG of {shape[0]} x {shape[1]} pixels (H x W, the recorded image_size): "
                             f"its header says {png_size(data)}")
        if depth != 8 or PNG_CHANNEL_AXES.get(colour) != shape[2:]:
            raise ValueError(f"expected an 8-bit {'RGB' if shape[2:] else 'grey'} PNG, its header says bit depth "
                             f"{depth}, colour type {colour}")
    with unreadable("PNG"), Image.open(io.BytesIO(data)) as image:
        pixels = np.array(image)
    if shape is not None and (pixels.shape != shape or pixels.dtype != np.uint8):
        raise ValueError(f"decodes to {pixels.dtype} {pixels.shape}, expected uint8 {shape}")
    return pixels


def _read_mat(data: bytes, shape: tuple[int, ...] | None = None) -> np.ndarray:
    """The float64 variable ``H`` of a MATLAB 5 file of at most :data:`MAT_LIMIT` bytes, of ``shape``
    (None: 3 x 3), checked by its header before its data is read."""
    shape = shape or (3, 3)
    if len(data) > MAT_LIMIT:
        raise ValueError(f"holds {len(data)} bytes, more than the {MAT_LIMIT} of a homography's MATLAB file")
    with unreadable("MATLAB file"):
        variables = {name: (size, kind) for name, size, kind in scipy.io.whosmat(io.BytesIO(data))}
    if "H" not in variables:
        raise ValueError(f"no variable 'H' (it holds {sorted(variables)})")
    size, kind = variables["H"]
    if kind != "double" or tuple(size) != shape:
        raise ValueError(f"holds 'H' of shape {tuple(size)}, class {kind}; expected {shape} double")
    with unreadable("MATLAB file"):
        H = scipy.io.loadmat(io.BytesIO(data), variable_names=["H"])["H"]
    if H.dtype != np.float64 or H.shape != tuple(size):
        raise ValueError(f"holds 'H' of {H.dtype} {H.shape}, its header says {tuple(size)} double")
    return H


def _read_npy(data: bytes, shape: tuple[int, ...] | None = None, dtype: Any = np.float64) -> np.ndarray:
    """A ``dtype`` (float64, or float32 for the float outputs) array of a ``.npy`` file (format 1.0 or
    2.0, little-endian, no pickles), of ``shape`` if given: its header is checked against ``dtype``,
    ``shape`` and the bytes the file holds before the array is made."""
    f = io.BytesIO(data)
    with unreadable(".npy file"):
        version = np.lib.format.read_magic(f)
        read_header = {(1, 0): np.lib.format.read_array_header_1_0, (2, 0): np.lib.format.read_array_header_2_0}
        declared, fortran_order, declared_dtype = read_header[version](f)
    expected = np.dtype(dtype).newbyteorder("<")
    if declared_dtype != expected or fortran_order or (shape is not None and declared != shape):
        raise ValueError(f"its header declares {declared_dtype}{' (Fortran order)' if fortran_order else ''} of shape "
                         f"{declared}, expected {shape or 'an array'} of {expected.name}")
    count, size = len(data) - f.tell(), expected.itemsize * math.prod(declared)
    if count != size:
        raise ValueError(f"holds {count} bytes of data, its header declares {size}")
    return np.frombuffer(data, expected, offset=f.tell()).reshape(declared).astype(np.dtype(dtype).newbyteorder("="))


def _json_integer(text: str) -> int:
    """A JSON integer, unless it has more digits than are read (then ``ValueError`` saying how many)."""
    problem = long_integer_text(text)
    if problem:
        raise ValueError(problem)
    return int(text)


def read_json(data: bytes, shape: None = None) -> Any:
    """The value the UTF-8 JSON ``data`` holds.

    Raises:
        ValueError: not UTF-8, not valid JSON, nested too deeply to parse, or an integer of more
            digits than are read (:func:`sidar_torch.config.numbers.long_integer_text`).
    """
    try:
        return json.loads(data.decode("utf-8"), parse_int=_json_integer)
    except UnicodeDecodeError as error:
        raise ValueError(f"not UTF-8 text ({error})") from None
    except (ValueError, RecursionError) as error:
        raise ValueError(f"not valid JSON ({type(error).__name__}: {error})") from None


ENCODERS: dict[str, Callable[[Any], bytes]] = {".png": _png, ".mat": _mat, ".npy": _npy, ".json": _json}
"""Entry extension -> encoder: ``.png`` uint8 ``(H, W)`` or ``(H, W, 3)``, ``.mat`` a 3 x 3 float64
``H``, ``.npy`` an array (the export writes float64 homographies and float32 float outputs), ``.json`` a dict."""

DECODERS: dict[str, Callable[[bytes, Any], Any]] = {".png": _read_png, ".mat": _read_mat, ".npy": _read_npy,
                                                     ".json": read_json}
"""Entry extension -> decoder, the inverse of :data:`ENCODERS` for what the export writes (``.npy``:
float64; :func:`decode` reads other dtypes): ``(data, shape)`` -> value, checking ``shape`` (None: any) before anything of its
size is made."""


def encode(entries: dict[str, Any]) -> dict[str, bytes]:
    """``{name: value}`` -> ``{name: bytes}``, each by its name's extension."""
    return {name: ENCODERS[os.path.splitext(name)[1]](value) for name, value in entries.items()}


def decode(name: str, data: bytes, shape: tuple[int, ...] | None = None, dtype: Any = None) -> Any:
    """The value of entry ``name`` from its ``data``, by the name's extension (:data:`DECODERS`), in
    memory bounded by ``len(data)`` and ``shape``.

    Args:
        shape: the array's expected shape (a ``.png``: ``(H, W)`` grey or ``(H, W, 3)`` RGB, 8-bit;
            a ``.npy``: any, float64; a ``.mat``: (3, 3) unless given), checked against the file's
            header before anything of its size is decoded, inflated or allocated; None: any (a
            ``.mat`` is still 3 x 3). Not used for ``.json``.
        dtype: a ``.npy``'s dtype, checked from its header (None: float64); for no other kind.

    Raises:
        ValueError: ``data`` is not a file of the kind its name says (truncated, of another kind or
            shape, a ``.mat`` without ``H``); the message says what is wrong, not which file.
    """
    extension = os.path.splitext(name)[1]
    if dtype is None:
        return DECODERS[extension](data, shape)
    if extension != ".npy":
        raise ValueError(f"dtype: only a .npy entry has one to check, not {name!r}")
    return _read_npy(data, shape, dtype)
