"""Presets and YAML files: ``load_config`` and ``available_presets``.

The presets are YAML files shipped inside the package (``sidar_torch/config/presets/``), so an
installed wheel loads them wherever it runs. A YAML file of the user's own may name a ``base``
(a preset name, or a path relative to the file) and override some of its fields.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import yaml

from .fields import SidarConfig
from .validation import check_names

__all__ = ["PRESET_DIR", "available_presets", "load_config"]

PRESET_DIR = Path(__file__).resolve().parent / "presets"
"""Folder of the YAML presets, inside the installed package."""


def available_presets() -> list[str]:
    """Names of the presets (``sidar_torch/config/presets/<name>.yaml``), sorted."""
    return sorted(p.stem for p in PRESET_DIR.glob("*.yaml"))


def _parse(path: Path) -> dict[str, Any]:
    """The mapping a YAML file holds.

    Raises:
        ValueError: malformed YAML (the message names the file, line and column) or not a mapping.
    """
    try:
        data = yaml.safe_load(path.read_text())
    except yaml.MarkedYAMLError as error:
        mark = error.problem_mark or error.context_mark
        where = f", line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        problem = " ".join(str(p) for p in (error.context, error.problem) if p)
        raise ValueError(f"config file {str(path)!r}{where}: malformed YAML ({problem})") from error
    except yaml.YAMLError as error:
        raise ValueError(f"config file {str(path)!r}: malformed YAML ({error})") from error
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ValueError(f"config file {str(path)!r}: expected a mapping of fields, got {type(data).__name__}")
    return data


def _read_yaml(source: str | os.PathLike, seen: tuple[Path, ...] = ()) -> dict[str, Any]:
    """Fields of a preset name or YAML path, with its ``base`` chain resolved (base first)."""
    path = Path(source)
    if path.suffix not in (".yaml", ".yml"):
        if str(source) not in available_presets():
            raise ValueError(f"config {str(source)!r}: not a preset ({available_presets()}) nor a YAML path")
        path = PRESET_DIR / f"{source}.yaml"
    if not path.is_file():
        raise FileNotFoundError(f"config file {str(path)!r} does not exist")
    if path.resolve() in seen:
        raise ValueError(f"config {str(path)!r}: 'base' chain loops back to itself")
    data = _parse(path)
    base = data.pop("base", None)
    check_names(data, SidarConfig, f"field in {str(path)!r}:")
    if base is None:
        return data
    base_path = base if str(base) in available_presets() else path.parent / str(base)
    return {**_read_yaml(base_path, seen + (path.resolve(),)), **data}


def load_config(preset: str | os.PathLike | SidarConfig | None = "misaligned", **overrides: Any) -> SidarConfig:
    """Load a preset by name (see :func:`available_presets`) or a YAML path, and apply keyword overrides.

    Args:
        preset: preset name, path to a YAML file, an existing ``SidarConfig``, or ``None`` for the
            built-in defaults.
        **overrides: field values replacing the preset's, e.g. ``image_size=(384, 512)`` (``(H, W)``),
            ``n_lights=(0, 2)``; numbers may be NumPy or 0-d torch scalars.

    Raises:
        ValueError: unknown preset or field (with the closest field names), malformed YAML (naming
            the file and line), or a value out of its allowed range (the message names the field).
        FileNotFoundError: a YAML path, or a ``base`` it names, does not exist.
    """
    check_names(overrides, SidarConfig, "override")
    if isinstance(preset, SidarConfig):
        return preset.replace(**overrides)
    fields = {} if preset is None else _read_yaml(preset)
    return SidarConfig(**{**fields, **overrides})
