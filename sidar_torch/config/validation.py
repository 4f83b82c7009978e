"""Turning field values as users write them into the config's types, and checking them.

Every error, a wrong type included, is a ``ValueError`` whose message starts with ``config field
'<name>'`` (``config fields '<a>', '<b>'`` for a rule between fields, or names the unknown field),
says what was expected, and shows what was given. Sizes read ``(H, W)``. Every number field has
finite ``bounds`` (field metadata), so a config that passes holds no number that overflows, hangs
the scene sampler or gives NaN.
"""

from __future__ import annotations

import dataclasses
import difflib
import itertools
import math
from typing import Any, Mapping

import numpy as np

from ..choices.lenses import LEAST_SLOPE, LENS_MODELS, NO_LENS, lens_folds
from ..choices.render import AUTO_MAP_SIZE, shadow_map_side
from ..choices.outputs import OUTPUTS
from .allowed import MAX_CAMERA_DISTANCE, MAX_GL_SIZE, MAX_SAMPLE_BYTES, MAX_SHADOWED_LIGHTS
from .memory import estimated_sample_bytes, shadowed_emitters
from .numbers import as_float, as_int, shown

__all__ = ["bounds_text", "check_field", "check_names", "coerce", "did_you_mean", "validate"]


def box_tilt_limit_deg(camera_xy: float, lowest_height: float) -> float:
    """The steepest tilt, in degrees, of a camera drawn from the box ``|x|, |y| <= camera_xy`` at heights
    ``>= lowest_height``: at a corner of the square at the lowest height, ``atan(sqrt(2) camera_xy / z)``."""
    return math.degrees(math.atan2(math.sqrt(2) * camera_xy, lowest_height))


_PAIRS = {"Range": "(low, high)", "IntRange": "(low, high)", "tuple[int, int]": "(H, W)"}
"""The two-number field types and how their two numbers read."""


def _as_tuple(name: str, value: Any) -> tuple:
    """``value``, a list, tuple, 1-d array or tensor, as a tuple of its elements.

    Raises:
        ValueError: a string, set, mapping, 0-d array or tensor, scalar or iterator (no length).
    """
    if isinstance(value, (str, bytes, set, frozenset, dict)) or getattr(value, "ndim", None) == 0 \
            or not hasattr(value, "__iter__") or not hasattr(value, "__len__"):
        # Sets are refused: their order follows string hashing, which changes between processes.
        raise ValueError(f"{name}: expected a list or tuple, got {shown(value)}")
    return tuple(value)


def coerce(f: dataclasses.Field, value: Any) -> Any:
    """``value`` in the type of field ``f``: lists become tuples, numbers (Python, NumPy, 0-d torch)
    plain ``int`` or ``float`` as the field's type asks, words must be ``str``.

    Raises:
        ValueError: a value of the wrong kind or length (the message names the field). A wrong type
            is a ``ValueError`` too, like a wrong value, so ``except ValueError`` catches every
            mistake in a config.
    """
    name = f"config field {f.name!r}"
    kind = str(f.type)
    if kind.startswith(("Range", "IntRange", "tuple")):
        value = _as_tuple(name, value)
        pair = _PAIRS.get(kind)
        if pair and len(value) != 2:
            raise ValueError(f"{name}: expected 2 values {pair}, got {len(value)}: {shown(value)}")
        if kind == "Range":
            value = tuple(as_float(name, v, finite=False) for v in value)
            if not all(map(math.isfinite, value)):
                raise ValueError(f"{name}: expected finite numbers (values are drawn uniformly from (low, high), "
                                 f"so both ends must be finite), got {shown(value)}")
        elif pair:
            value = tuple(as_int(name, v) for v in value)
        elif not all(isinstance(v, str) for v in value):
            raise ValueError(f"{name}: expected a list of words from {f.metadata['choices']}, got {shown(value)}")
    elif kind == "MapSize":
        if isinstance(value, str) and value != AUTO_MAP_SIZE:
            raise ValueError(f"{name}: expected a power of two or {AUTO_MAP_SIZE!r}, got {shown(value)}")
        value = value if isinstance(value, str) else as_int(name, value)
    elif kind == "float":
        value = as_float(name, value)
    elif kind == "int":
        value = as_int(name, value)
    elif kind == "bool" and not isinstance(value, bool):
        raise ValueError(f"{name}: expected true or false, got {shown(value)}")
    elif kind == "str" and not isinstance(value, str):
        raise ValueError(f"{name}: expected one of {f.metadata['choices']}, got {shown(value)}")
    return value


_RANGE_BOUNDS = ("a range (low, high) with {lo} <= low <= high <= {hi}", lambda v, lo, hi: lo <= v[0] <= v[1] <= hi)
_NUMBER_BOUNDS = ("{lo} <= value <= {hi}", lambda v, lo, hi: lo <= v <= hi)
_BOUNDED = {
    "Range": _RANGE_BOUNDS,
    "IntRange": _RANGE_BOUNDS,
    "tuple[int, int]": ("(H, W) with {lo} <= H, W <= {hi}", lambda v, lo, hi: all(lo <= s <= hi for s in v)),
    "int": _NUMBER_BOUNDS,
    "float": _NUMBER_BOUNDS,
    "MapSize": (f"{AUTO_MAP_SIZE}, or {{lo}} <= value <= {{hi}}", lambda v, lo, hi: v == AUTO_MAP_SIZE or lo <= v <= hi),
}
"""Per field type, what its ``bounds`` metadata ``(lo, hi)`` mean: the text and the check."""


def bounds_text(f: dataclasses.Field) -> str:
    """What field ``f``'s ``bounds`` allow, e.g. ``"0 <= value <= 100"`` (the schema prints it too)."""
    lo, hi = f.metadata["bounds"]
    return _BOUNDED[str(f.type)][0].format(lo=f"{lo:g}", hi=f"{hi:g}")


def _within_bounds(f: dataclasses.Field, value: Any) -> bool:
    """Whether the coerced ``value`` of field ``f`` lies within its ``bounds``."""
    lo, hi = f.metadata["bounds"]
    return _BOUNDED[str(f.type)][1](value, lo, hi)


def _check_allowed(f: dataclasses.Field, value: Any) -> None:
    """Check the coerced ``value`` of field ``f`` against its ``bounds`` or ``choices`` metadata.

    Raises:
        ValueError: ``config field '<name>': expected <what the metadata allows>, got <value>``.
    """
    def need(ok: bool, expected: str) -> None:
        if not ok:
            raise ValueError(f"config field {f.name!r}: expected {expected}, got {shown(value)}")

    if "bounds" in f.metadata:
        need(_within_bounds(f, value), bounds_text(f))
    if "choices" in f.metadata and isinstance(value, tuple):
        choices = f.metadata["choices"]
        need(len(value) > 0 and set(value) <= set(choices), f"a non-empty subset of {choices}")
    elif "choices" in f.metadata:
        need(value in f.metadata["choices"], f"one of {f.metadata['choices']}")


def check_field(f: dataclasses.Field, value: Any) -> Any:
    """``value`` in the type of field ``f`` (:func:`coerce`) and within its ``bounds`` or ``choices``:
    what a ``SidarConfig`` checks of one field alone (the rules between fields are :func:`validate`'s).

    Raises:
        ValueError: as :func:`coerce`, or a value out of its bounds (the message names the field).
    """
    value = coerce(f, value)
    _check_allowed(f, value)
    return value


def validate(config: Any) -> None:
    """Check the coerced fields of a ``SidarConfig`` against their ``bounds`` and ``choices``
    metadata and the rules between fields (the camera box's tilt, the shadow maps the renderer can
    bind, flow's least image size, the lens, the memory a sample needs).

    Raises:
        ValueError: the first field out of range (the message names it and what was expected).
    """
    def need(ok: bool, name: str, expected: str) -> None:
        if not ok:
            raise ValueError(f"config field {name!r}: expected {expected}, got {shown(getattr(config, name))}")

    c = config
    for f in dataclasses.fields(c):
        _check_allowed(f, getattr(c, f.name))
    reach = box_tilt_limit_deg(c.camera_xy, c.camera_height[0])
    need(c.max_tilt_deg == 90 or c.max_tilt_deg <= reach, "max_tilt_deg",
         f"at most {reach:.4g} deg, the steepest tilt of the camera box (x, y within camera_xy={c.camera_xy:.4g} "
         f"at heights from camera_height[0]={c.camera_height[0]:.4g}); raise camera_xy or lower camera_height "
         f"for grazing views, or set 90 for no limit")
    need(c.reference_height == (0.0, 0.0) or c.reference_height[0] >= 1e-3, "reference_height",
         f"(0, 0) (drawn from camera_height) or a range (low, high) with 0.001 <= low <= high <= {MAX_CAMERA_DISTANCE:g}")
    size = c.shadow_map_size
    need(size == AUTO_MAP_SIZE or size & (size - 1) == 0, "shadow_map_size",
         f"a power of two from 16 to {MAX_GL_SIZE}, or {AUTO_MAP_SIZE!r}")
    need(shadowed_emitters(c) <= MAX_SHADOWED_LIGHTS, "area_light_samples",
         f"n_lights[1] * area_light_samples <= {MAX_SHADOWED_LIGHTS} (shadow maps the renderer can bind; "
         f"config field 'n_lights' is {c.n_lights})")
    _check_image_sides(c)
    _check_lens(c)
    _check_memory(c)


def _check_image_sides(config: Any) -> None:
    """Each optional output switched on needs an image of at least its row's ``min_image_side`` pixels a
    side (``choices.outputs.OUTPUTS``)."""
    for row in OUTPUTS.values():
        if getattr(config, row.switch) and min(config.image_size) < row.min_image_side:
            side = row.min_image_side
            raise ValueError(f"config fields {row.switch!r} and 'image_size': expected an image_size of at least "
                             f"{side} x {side} pixels (H, W) with {row.switch} true ({row.name} reads the pixel "
                             f"centres around each point), got {config.image_size}; set {row.switch} false or "
                             f"enlarge image_size")


def _check_lens(config: Any) -> None:
    """With a lens, no output a lens may not resample (``OptionalOutput.lens_resample``: depth and flow, of
    pinhole cameras only), and no lens of its ranges may fold the view over the image
    (``choices.lenses.lens_folds``, the renderer's and the export reader's test too): every corner of the box of
    ranges is tried, tangential terms included, where the worst lens of the box lies (a lens folds more the lower
    its radial coefficients and the larger its tangential ones)."""
    if config.lens_model == NO_LENS:
        return
    for row in OUTPUTS.values():  # a pinhole's values; a lens would resample them wrongly
        if not row.lens_resample and getattr(config, row.switch):
            raise ValueError(f"config field {row.switch!r}: expected false with lens_model {config.lens_model!r} "
                             f"({row.name} is rendered for pinhole cameras only, lens_model none), got true")
    fields = LENS_MODELS[config.lens_model].fields
    corners = np.array(list(itertools.product(*(getattr(config, f) if f else (0.0, 0.0) for f in fields))))
    folding = lens_folds(config.lens_model, corners)
    if not folding.any():
        return
    corner = corners[folding][0]
    named = [f for f in fields if f is not None]
    tangential = [f for f in ("lens_p1", "lens_p2") if f in fields]
    radial = corner * [f not in tangential for f in fields]
    why = (f" (with {' and '.join(tangential)} at 0 it would not: the tangential terms fold it)"
           if tangential and not lens_folds(config.lens_model, radial) else "")
    raise ValueError(f"config fields {', '.join(map(repr, named))}: expected ranges of lens_model "
                     f"{config.lens_model!r} whose every lens bends the image without folding it (the distortion's "
                     f"Jacobian keeping its eigenvalues above {LEAST_SLOPE:g} out to the image's corner, so that every "
                     f"pixel has one source: choices.lenses.lens_folds), got "
                     f"{', '.join(f'{f}={shown(getattr(config, f))}' for f in named)}, whose lens "
                     f"{tuple(float(c) for c in corner)} at the corner folds it{why}: narrow the ranges towards 0")


def _check_memory(config: Any) -> None:
    """Refuse a config whose sample needs more than ``MAX_SAMPLE_BYTES`` (``memory.estimated_sample_bytes``)."""
    need = estimated_sample_bytes(config)
    if need > MAX_SAMPLE_BYTES:
        (h, w), maps = config.image_size, max(1, shadowed_emitters(config) if config.shadows else 0)
        raise ValueError(
            f"config fields 'image_size', 'n_views' and 'shadow_map_size': a sample of {config.n_views} views of "
            f"{h} x {w} (H x W) pixels with {maps} shadow maps of "
            f"{shadow_map_side(config.shadow_map_size, config.image_size)}^2 texels (antialias "
            f"{config.antialias}) needs about {need / 2**30:.3g} GiB (sidar_torch.config.memory's estimate), more "
            f"than the {MAX_SAMPLE_BYTES / 2**30:g} GiB a sample may use; lower image_size, n_views or shadow_map_size")


def did_you_mean(name: str, known: list[str]) -> str:
    """`` (did you mean 'a' or 'b'?)`` naming the (up to 3) entries of ``known`` closest to ``name``
    (``difflib``), or ``""`` if none is close."""
    close = difflib.get_close_matches(name, known, n=3, cutoff=0.6)
    return f" (did you mean {' or '.join(repr(c) for c in close)}?)" if close else ""


def check_names(values: Mapping[str, Any], config_class: type, what: str) -> None:
    """Refuse keys of ``values`` that are no field of ``config_class``, suggesting the closest names.

    Args:
        what: what the keys are, for the message (``"override"``, ``"field in 'mine.yaml':"``).

    Raises:
        ValueError: ``unknown config <what> 'name' (did you mean 'a' or 'b'?)``, one clause per unknown key.
    """
    known = [f.name for f in dataclasses.fields(config_class)]
    unknown = sorted(set(values) - set(known), key=str)
    if unknown:
        clauses = [f"{name!r}{did_you_mean(str(name), known)}" for name in unknown]
        raise ValueError(f"unknown config {what} {', '.join(clauses)}; `python -m sidar_torch schema` lists "
                         f"the {len(known)} fields")
