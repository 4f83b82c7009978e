"""Numbers as users pass them: Python, NumPy and PyTorch scalars, turned into plain ``int`` or ``float``.

Every layer that takes a number from a user (config fields, API arguments) converts it here, so
``np.int64(3)``, ``np.float32(0.5)`` and ``torch.tensor(192)`` are accepted wherever ``3``, ``0.5``
and ``192`` are. Booleans (``True``, ``np.bool_``, a bool tensor) are refused: they are numbers to
Python but almost always a mistake where a count or a length is expected.
"""

from __future__ import annotations

import math
import numbers
import reprlib
from typing import Any

__all__ = ["as_float", "as_int", "shown"]

_SHORT = reprlib.Repr()
_SHORT.maxlong, _SHORT.maxstring, _SHORT.maxother = 40, 60, 60


def shown(value: Any) -> str:
    """``repr(value)`` cut to a readable length for an error message (``10**400`` shows 40 digits)."""
    return _SHORT.repr(value)


def _scalar(name: str, value: Any) -> int | float:
    """``value`` as a Python ``int`` or ``float``: a 0-d array or tensor is unwrapped with ``.item()``.

    Raises:
        ValueError: ``value`` is a bool, not a real number, or an array with more than one element.
    """
    if getattr(value, "ndim", None) == 0 and hasattr(value, "item"):  # 0-d numpy array or torch tensor
        value = value.item()
    if isinstance(value, bool) or not isinstance(value, numbers.Real):  # np.bool_ is no numbers.Real
        raise ValueError(f"{name}: expected a number, got {shown(value)}")
    return int(value) if isinstance(value, numbers.Integral) else float(value)


def as_int(name: str, value: Any, minimum: int | None = None) -> int:
    """``value`` as a Python ``int``: any integer scalar (Python, NumPy of any width, a 0-d integer
    tensor), or a float with an integral value (``3.0``).

    Args:
        name: what the value is, for the error (e.g. ``"config field 'n_views'"``, ``"seed"``).
        minimum: the least value allowed, if any.

    Raises:
        ValueError: a bool, not a number, not integral, or below ``minimum`` (the message starts with ``name``).
    """
    number = _scalar(name, value)
    if isinstance(number, float) and not number.is_integer():
        raise ValueError(f"{name}: expected an integer, got {shown(value)}")
    if minimum is not None and number < minimum:
        raise ValueError(f"{name}: expected an integer >= {minimum}, got {shown(value)}")
    return int(number)


def as_float(name: str, value: Any, *, finite: bool = True) -> float:
    """``value`` as a Python ``float``: any integer or floating scalar (Python, NumPy of any width,
    a 0-d tensor); finite unless ``finite`` is false (then NaN and infinities pass, for a caller
    that explains them itself).

    An integer too large for a float (``10**400``) counts as infinite; ``-0.0`` becomes ``0.0``.

    Raises:
        ValueError: a bool, not a number, or (if ``finite``) NaN or infinite (the message starts with ``name``).
    """
    try:
        number = float(_scalar(name, value))
    except OverflowError:  # an integer beyond float's range, e.g. 10**400
        number = math.inf
    if finite and not math.isfinite(number):
        raise ValueError(f"{name}: expected a finite number, got {shown(value)}")
    return number + 0.0  # -0.0 becomes 0.0: numpy's uniform(0.0, -0.0) raises "high - low < 0"
