"""Turning field values as users write them into the config's types, and checking them.

Every error is a ``ValueError`` whose message starts with ``config field '<name>'`` (or names the
unknown field), says what was expected, and shows what was given. Sizes read ``(H, W)``.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
from typing import Any, Mapping

from .allowed import ANTIALIAS_SAMPLES, MAX_GL_SIZE, MAX_SHADOWED_LIGHTS
from .numbers import as_float, as_int

__all__ = ["check_names", "coerce", "validate"]


def box_tilt_limit_deg(camera_xy: float, lowest_height: float) -> float:
    """The steepest tilt, in degrees, of a camera drawn from the box ``|x|, |y| <= camera_xy`` at heights
    ``>= lowest_height``: at a corner of the square at the lowest height, ``atan(sqrt(2) camera_xy / z)``."""
    return math.degrees(math.atan2(math.sqrt(2) * camera_xy, lowest_height))


def coerce(f: dataclasses.Field, value: Any) -> Any:
    """``value`` in the type of field ``f``: lists become tuples, numbers (Python, NumPy, 0-d torch)
    plain ``int`` or ``float`` as the field's type asks.

    Raises:
        ValueError: a value of the wrong kind or length (the message names the field).
    """
    name = f"config field {f.name!r}"
    kind = str(f.type)
    if kind.startswith(("Range", "IntRange", "tuple")):
        if isinstance(value, (str, bytes, set, frozenset, dict)) or not hasattr(value, "__iter__"):
            # Sets are refused: their order follows string hashing, which changes between processes.
            raise ValueError(f"{name}: expected a list or tuple, got {value!r}")
        value = tuple(value)
        pair = {"Range": "(low, high)", "IntRange": "(low, high)", "tuple[int, int]": "(H, W)"}.get(kind)
        if pair and len(value) != 2:
            raise ValueError(f"{name}: expected 2 values {pair}, got {len(value)}: {value!r}")
        if kind == "Range":
            value = tuple(as_float(name, v, finite=False) for v in value)
            if not all(map(math.isfinite, value)):
                raise ValueError(f"{name}: expected finite numbers (values are drawn uniformly from (low, high), "
                                 f"so both ends must be finite), got {value!r}")
        elif pair:
            value = tuple(as_int(name, v) for v in value)
    elif kind == "float":
        value = as_float(name, value)
    elif kind == "int":
        value = as_int(name, value)
    elif kind == "bool" and not isinstance(value, bool):
        raise ValueError(f"{name}: expected true or false, got {value!r}")
    return value


def validate(config: Any) -> None:
    """Check the coerced fields of a ``SidarConfig`` against their ``bounds`` and ``choices``
    metadata and the rules between fields.

    Raises:
        ValueError: the first field out of range (the message names it and what was expected).
    """
    def need(ok: bool, name: str, expected: str) -> None:
        if not ok:
            raise ValueError(f"config field {name!r}: expected {expected}, got {getattr(config, name)!r}")

    c = config
    need(all(s >= 1 for s in c.image_size), "image_size", "(H, W) with H, W >= 1")
    need(all(s <= MAX_GL_SIZE for s in c.image_size), "image_size",
         f"(H, W) with H, W <= {MAX_GL_SIZE} (the largest renderbuffer side of Mesa's llvmpipe)")
    need(c.n_views >= 1, "n_views", "at least 1")
    need(c.camera_xy >= 0, "camera_xy", ">= 0")
    need(0 <= c.max_tilt_deg <= 90, "max_tilt_deg", "0 <= max_tilt_deg <= 90 (90: no limit)")
    reach = box_tilt_limit_deg(c.camera_xy, c.camera_height[0])
    need(c.max_tilt_deg == 90 or c.max_tilt_deg <= reach, "max_tilt_deg",
         f"at most {reach:.4g} deg, the steepest tilt of the camera box (x, y within camera_xy={c.camera_xy:.4g} "
         f"at heights from camera_height[0]={c.camera_height[0]:.4g}); raise camera_xy or lower camera_height "
         f"for grazing views, or set 90 for no limit")
    need(c.light_xy >= 0, "light_xy", ">= 0")
    need(c.occluder_xy >= 0, "occluder_xy", ">= 0")
    need(0 <= c.min_coverage <= 1, "min_coverage", "a fraction in [0, 1]")
    need(0 <= c.min_overlap <= 1, "min_overlap", "a fraction in [0, 1]")
    need(0 <= c.light_saturation_max <= 1, "light_saturation_max", "a value in [0, 1]")
    need(c.area_light_size > 0, "area_light_size", "> 0")
    need(c.area_light_samples >= 1, "area_light_samples", "at least 1")
    need(0 <= c.mask_min_opacity <= 1, "mask_min_opacity", "a value in [0, 1]")
    size = c.shadow_map_size
    need(size >= 16 and size & (size - 1) == 0, "shadow_map_size", "a power of two >= 16")
    need(size <= MAX_GL_SIZE, "shadow_map_size",
         f"a power of two <= {MAX_GL_SIZE} (the largest texture side of Mesa's llvmpipe)")
    need(c.mesh_error_px >= 0, "mesh_error_px", ">= 0 (pixels)")
    need(c.antialias in ANTIALIAS_SAMPLES, "antialias", f"one of {ANTIALIAS_SAMPLES} (samples per pixel)")
    need(c.max_image_pixels >= 1, "max_image_pixels", "at least 1 (pixels)")
    for f in dataclasses.fields(c):
        value = getattr(c, f.name)
        if "choices" in f.metadata and isinstance(value, tuple):
            choices = f.metadata["choices"]
            need(len(value) > 0 and set(value) <= set(choices), f.name, f"a non-empty subset of {choices}")
        elif "choices" in f.metadata:
            need(value in f.metadata["choices"], f.name, f"one of {f.metadata['choices']}")
        if "bounds" in f.metadata:
            lo, hi = f.metadata["bounds"]
            low, high = value
            need(lo <= low <= high <= hi, f.name, f"a range (low, high) with {lo} <= low <= high <= {hi}")
    samples = c.area_light_samples if "area" in c.light_types else 1
    need(c.n_lights[1] * samples <= MAX_SHADOWED_LIGHTS, "area_light_samples",
         f"n_lights[1] * area_light_samples <= {MAX_SHADOWED_LIGHTS} (shadow maps the renderer can bind)")


def check_names(values: Mapping[str, Any], config_class: type, what: str) -> None:
    """Refuse keys of ``values`` that are no field of ``config_class``, suggesting the closest names.

    Args:
        what: what the keys are, for the message (``"override"``, ``"field in 'mine.yaml':"``).

    Raises:
        ValueError: ``unknown config <what> 'name' (did you mean 'a' or 'b'?)``, one clause per unknown key.
    """
    known = [f.name for f in dataclasses.fields(config_class)]
    unknown = sorted(set(values) - set(known))
    if unknown:
        clauses = []
        for name in unknown:
            close = difflib.get_close_matches(str(name), known, n=3, cutoff=0.6)
            hint = f" (did you mean {' or '.join(repr(c) for c in close)}?)" if close else ""
            clauses.append(f"{name!r}{hint}")
        raise ValueError(f"unknown config {what} {', '.join(clauses)}; `python -m sidar_torch schema` lists "
                         f"the {len(known)} fields")
