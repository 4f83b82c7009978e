"""The bytes of an export's entries, by the entry name's extension: :data:`ENCODERS` turns a value
into bytes, :data:`DECODERS` reads it back (``.png`` 8-bit images, ``.mat`` a homography for MATLAB,
``.npy`` arrays, ``.json`` dicts); :func:`png_size` reads a PNG's size without decoding it.
"""

from __future__ import annotations

import io
import json
import os
import struct
from typing import Any, Callable

import numpy as np
import scipy.io
from PIL import Image

__all__ = ["DECODERS", "ENCODERS", "MAT_HEADER", "decode", "encode", "png_size"]

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


def png_size(data: bytes) -> tuple[int, int] | None:
    """``(H, W)`` pixels from the header of the PNG ``data`` (nothing decoded), or None if it is not a PNG."""
    if len(data) < 24 or not data.startswith(PNG_SIGNATURE) or data[12:16] != b"IHDR":
        return None
    width, height = struct.unpack(">II", data[16:24])
    return height, width


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
    """The value of entry ``name`` from its ``data``, by the name's extension (:data:`DECODERS`)."""
    return DECODERS[os.path.splitext(name)[1]](data)
