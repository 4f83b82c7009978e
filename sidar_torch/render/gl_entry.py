"""GL functions called through ctypes prototypes, without PyOpenGL's wrappers, for the calls a view makes
many times (uniform arrays, draws).

PyOpenGL's entry points find a handler for each argument, convert and check it, and ask GL for its error
after every call: several times the cost of the call itself (``glDrawElementsInstanced``: 3.6 us against
0.65 us). A function fetched here takes plain ctypes arguments, which reach GL as PyOpenGL would pass them.
GL's error flag stays set until it is read, so an error of one of these calls raises at the next call made
through PyOpenGL, which checks it.
"""

from __future__ import annotations

import ctypes
import functools
from typing import Callable

from OpenGL import platform

__all__ = ["gl_entry"]


@functools.cache
def gl_entry(name: str, prototype: type) -> Callable:
    """The GL function ``name`` (e.g. ``"glUniform3fv"``) of the platform's GL library, called through
    ``prototype`` (a ``ctypes.CFUNCTYPE``); looked up once per process.

    Raises:
        AttributeError: the library has no function ``name``.
    """
    return prototype(ctypes.cast(platform.PLATFORM.GL[name], ctypes.c_void_p).value)
