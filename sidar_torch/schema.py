"""The configuration schema: every ``SidarConfig`` field with its default, allowed values and meaning.

Generated from the dataclass itself (fields, defaults), :data:`sidar_torch.config.RANGE_BOUNDS` and
the class docstring (meanings), so it cannot drift from the code. ``python -m sidar_torch schema``
prints it as the markdown table the README carries (a test checks they are equal).
"""

from __future__ import annotations

import dataclasses
import math
import re
from typing import Any

from . import config
from .config import SidarConfig

__all__ = ["field_meanings", "schema_markdown", "schema_rows"]

_CHOICES = {"light_types": config.LIGHT_TYPES, "occluder_shapes": config.OCCLUDER_SHAPES,
            "occluder_materials": config.OCCLUDER_MATERIALS, "on_bad_image": config.ON_BAD_IMAGE,
            "background": config.BACKGROUNDS,
            "shadow_frustum": config.SHADOW_FRUSTA, "mesh_detail": config.MESH_DETAILS,
            "texture_filter": config.TEXTURE_FILTERS}


def field_meanings() -> dict[str, str]:
    """Each field's description from the ``SidarConfig`` docstring (``name[, name]: text`` entries,
    continuation lines joined); fields described together share the text."""
    meanings: dict[str, str] = {}
    names: list[str] = []
    for line in SidarConfig.__doc__.splitlines():
        entry = re.match(r"^ {8}([a-z_0-9]+(?:, [a-z_0-9]+)*): (.*)$", line)
        if entry:
            names = entry.group(1).split(", ")
            for name in names:
                meanings[name] = entry.group(2)
        elif names and re.match(r"^ {12}\S", line):
            for name in names:
                meanings[name] += " " + line.strip()
        else:
            names = []
    return meanings


def _format(value: Any) -> str:
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, float):
        return f"{value:.4g}" if math.isfinite(value) else ("inf" if value > 0 else "-inf")
    if isinstance(value, tuple):
        return ", ".join(_format(v) for v in value) if value and isinstance(value[0], str) else \
            "(" + ", ".join(_format(v) for v in value) + ")"
    return str(value)


def schema_rows() -> list[dict[str, str]]:
    """One row per field: ``name``, ``default``, ``allowed`` and ``meaning`` (strings)."""
    meanings = field_meanings()
    rows = []
    for f in dataclasses.fields(SidarConfig):
        if f.name in config.RANGE_BOUNDS:
            lo, hi = config.RANGE_BOUNDS[f.name]
            allowed = f"{_format(lo)} <= low <= high <= {_format(hi)}"
        elif f.name in _CHOICES:
            allowed = "any of " + ", ".join(_CHOICES[f.name]) if f.type.startswith("tuple") else \
                "one of " + ", ".join(_CHOICES[f.name])
        else:
            allowed = ""
        rows.append({"name": f.name, "default": _format(f.default), "allowed": allowed,
                     "meaning": meanings.get(f.name, "")})
    return rows


def schema_markdown() -> str:
    """The schema as a markdown table (backticks around names, ``|`` escaped)."""
    lines = ["| field | default | allowed | meaning |", "|---|---|---|---|"]
    for row in schema_rows():
        cells = [f"`{row['name']}`", row["default"], row["allowed"], row["meaning"].replace("``", "`")]
        lines.append("| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |")
    return "\n".join(lines)
