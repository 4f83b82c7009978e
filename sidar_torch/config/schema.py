"""The configuration schema: every ``SidarConfig`` field with its default, allowed values and meaning.

Generated from the dataclass itself (fields, defaults, and the ``meaning``, ``bounds`` and
``choices`` metadata), so it cannot drift from the code. ``python -m sidar_torch schema`` prints
it as a markdown table.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

from .fields import SidarConfig
from .validation import bounds_text

__all__ = ["schema_markdown", "schema_rows"]


def _format(value: Any) -> str:
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, float):
        return f"{value:.4g}" if math.isfinite(value) else ("inf" if value > 0 else "-inf")
    if isinstance(value, tuple):
        return ", ".join(_format(v) for v in value) if value and isinstance(value[0], str) else \
            "(" + ", ".join(_format(v) for v in value) + ")"
    return str(value)


def _allowed(f: dataclasses.Field) -> str:
    """What the field may hold, from its ``bounds`` or ``choices`` metadata ("" if neither)."""
    if "bounds" in f.metadata:
        return bounds_text(f)
    if "choices" in f.metadata:
        return ("any of " if f.type.startswith("tuple") else "one of ") + ", ".join(map(str, f.metadata["choices"]))
    return ""


def schema_rows() -> list[dict[str, str]]:
    """One row per field: ``name``, ``default``, ``allowed`` and ``meaning`` (strings)."""
    return [{"name": f.name, "default": _format(f.default), "allowed": _allowed(f), "meaning": f.metadata["meaning"]}
            for f in dataclasses.fields(SidarConfig)]


def schema_markdown() -> str:
    """The schema as a markdown table (backticks around names, ``|`` escaped)."""
    lines = ["| field | default | allowed | meaning |", "|---|---|---|---|"]
    for row in schema_rows():
        cells = [f"`{row['name']}`", row["default"], row["allowed"], row["meaning"].replace("``", "`")]
        lines.append("| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |")
    return "\n".join(lines)
