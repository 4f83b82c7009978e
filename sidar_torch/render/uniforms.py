"""Uniform arrays handed to GL through ctypes directly (``gl_entry``), without PyOpenGL's array handling.

A lit view sets about 120 vector and matrix uniforms. PyOpenGL's ``glUniform*v`` entry points find a
handler for each array argument, convert and check it, and ask GL for its error after every call. Here
each of those functions takes the values as bytes (the array converted to the uniform's 32-bit type, as
PyOpenGL converts it: the same bits reach GL).
"""

from __future__ import annotations

import ctypes
import functools

import numpy as np

from .gl_entry import gl_entry

__all__ = ["set_uniform_array"]

_TYPES = {"f": np.float32, "i": np.int32, "u": np.uint32}
"""Element kinds of the vector uniforms and the type GL reads them as."""

_VECTOR = ctypes.CFUNCTYPE(None, ctypes.c_int, ctypes.c_int, ctypes.c_char_p)
_MATRIX = ctypes.CFUNCTYPE(None, ctypes.c_int, ctypes.c_int, ctypes.c_ubyte, ctypes.c_char_p)


@functools.cache
def _function(key: tuple[int, str]):
    """The ctypes function for the uniforms of ``key``: a vector of ``n`` elements of ``kind``, or an
    ``n x n`` matrix (kind ``"m"``)."""
    n, kind = key
    if kind == "m":
        return gl_entry(f"glUniformMatrix{n}fv", _MATRIX)
    return gl_entry(f"glUniform{n}{'ui' if kind == 'u' else kind}v", _VECTOR)


def set_uniform_array(location: int, value: np.ndarray, kind: str = "f") -> None:
    """Set the uniform at ``location`` of the bound program to ``value``.

    Args:
        location: the uniform's location (not -1).
        value: ``(n,)`` for a vector uniform of ``n`` in 1..4 elements of ``kind`` (any numeric
            dtype, converted), or ``(n, n)`` for a ``mat{n}`` uniform, n in 2..4 (row major, any
            float dtype; GL transposes it).
        kind: a vector's element type: ``"f"`` float, ``"i"`` int, ``"u"`` uint.

    Raises:
        ValueError: a shape or kind GL has no uniform for.
    """
    if value.ndim == 2 and value.shape[0] == value.shape[1] and value.shape[0] in (2, 3, 4):
        _function((value.shape[0], "m"))(location, 1, 1, np.ascontiguousarray(value, dtype=np.float32).tobytes())
    elif value.ndim == 1 and value.shape[0] in (1, 2, 3, 4) and kind in _TYPES:
        _function((value.shape[0], kind))(location, 1, np.ascontiguousarray(value, dtype=_TYPES[kind]).tobytes())
    else:
        raise ValueError(f"no GL uniform for a value of shape {value.shape} and kind {kind!r}")
