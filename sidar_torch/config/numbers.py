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

__all__ = ["MAX_INTEGER_DIGITS", "as_float", "as_int", "long_integer_text", "shown"]

class _Short(reprlib.Repr):
    """reprlib's cut ``repr``, also of integers whose ``repr`` Python refuses (more than
    ``sys.get_int_max_str_digits()`` digits, 4300 by default, raise ``ValueError``)."""

    def repr_int(self, x: int, level: int) -> str:
        try:
            return super().repr_int(x, level)
        except ValueError:
            return f"<an integer of about {int(x.bit_length() * math.log10(2)) + 1} digits>"


_SHORT = _Short()
_SHORT.maxlong, _SHORT.maxstring, _SHORT.maxother = 40, 60, 60


def shown(value: Any) -> str:
    """``repr(value)`` cut to a readable length for an error message (``10**400`` shows 40 digits,
    ``10**5000`` ``<an integer of about 5001 digits>``)."""
    return _SHORT.repr(value)


MAX_INTEGER_DIGITS = 4300
"""Most digits of an integer read from a config or manifest file's text: Python's default limit
for decimal text (``sys.get_int_max_str_digits()``), whatever the interpreter's is set to, far
more than any number there may hold (converting a longer one takes time quadratic in its length)."""


def long_integer_text(text: str) -> str | None:
    """Why the integer written ``text`` (a YAML or JSON number: decimal, hex, sexagesimal ``1:30``)
    is not read, or None if it is: more than :data:`MAX_INTEGER_DIGITS` digits."""
    count = sum(c.isalnum() for c in text)
    if count > MAX_INTEGER_DIGITS:
        return f"an integer of {count} digits, more than the {MAX_INTEGER_DIGITS} read from a file"
    return None


def _scalar(name: str, value: Any) -> int | float:
    """``value`` as a Python ``int`` or ``float``: a 0-d array or tensor is unwrapped with ``.item()``.

    Raises:
        ValueError: ``value`` is a bool, not a real number, or an array with more than one element.
    """
    if getattr(value, "ndim", None) == 0 and hasattr(value, "item"):  # 0-d numpy array or torch tensor
        value = value.item()
    if isinstance(value, bool) or not isinstance(value, numbers.Real):  # np.bool_ and Decimal are no numbers.Real
        raise ValueError(f"{name}: expected a number, got {shown(value)}")
    if isinstance(value, numbers.Integral):
        return int(value)
    if isinstance(value, numbers.Rational) and value.denominator == 1:  # Fraction(6, 2): exactly 3
        return int(value.numerator)
    try:
        return float(value)
    except OverflowError:  # a Fraction beyond float's range, e.g. Fraction(10**400, 3)
        return math.inf if value > 0 else -math.inf


def as_int(name: str, value: Any, minimum: int | None = None, maximum: int | None = None) -> int:
    """``value`` as a Python ``int``: any integer scalar (Python, NumPy of any width, a 0-d integer
    tensor), or a float with an integral value (``3.0``).

    Args:
        name: what the value is, for the error (e.g. ``"config field 'n_views'"``, ``"seed"``).
        minimum, maximum: the least and the largest value allowed, if any.

    Raises:
        ValueError: a bool, not a number, not integral, below ``minimum`` or above ``maximum`` (the
            message starts with ``name`` and gives the range).
    """
    number = _scalar(name, value)
    if isinstance(number, float) and not number.is_integer():
        raise ValueError(f"{name}: expected an integer, got {shown(value)}")
    too_small, too_large = minimum is not None and number < minimum, maximum is not None and number > maximum
    if too_small or too_large:
        expected = (f">= {minimum}" if maximum is None else f"<= {maximum}" if minimum is None
                    else f"from {minimum} to {maximum}")
        raise ValueError(f"{name}: expected an integer {expected}, got {shown(value)}")
    return int(number)


def as_float(name: str, value: Any, *, finite: bool = True) -> float:
    """``value`` as a Python ``float``: any integer or floating scalar (Python, NumPy of any width,
    a 0-d tensor); finite unless ``finite`` is false (then NaN and infinities pass, for a caller
    that explains them itself).

    An integer too large for a float (``10**400``) counts as infinite; ``-0.0`` becomes ``0.0``.

    Raises:
        ValueError: a bool, not a number, or (if ``finite``) NaN or infinite (the message starts with ``name``).
    """
    number = _scalar(name, value)
    try:
        number = float(number)
    except OverflowError:  # an integer beyond float's range, e.g. 10**400
        number = math.inf if number > 0 else -math.inf
    if finite and not math.isfinite(number):
        raise ValueError(f"{name}: expected a finite number, got {shown(value)}")
    return number + 0.0  # -0.0 becomes 0.0: numpy's uniform(0.0, -0.0) raises "high - low < 0"
