"""Presets and YAML files: ``load_config`` and ``available_presets``.

The presets are YAML files shipped inside the package (``sidar_torch/config/presets/``), so an
installed wheel loads them wherever it runs. A YAML file of the user's own may name a ``base``
(a preset name, or a path relative to the file) and override some of its fields.
"""

from __future__ import annotations

import dataclasses
import os
import re
from pathlib import Path
from typing import Any

import yaml

from .fields import SidarConfig
from .files import read_regular
from .numbers import long_integer_text, shown
from .validation import check_field, check_names, did_you_mean

__all__ = ["PRESET_DIR", "available_presets", "load_config", "parse_yaml"]

PRESET_DIR = Path(__file__).resolve().parent / "presets"
"""Folder of the YAML presets, inside the installed package."""


class _Loader(yaml.SafeLoader):
    """PyYAML's safe loader, also reading YAML 1.2's floats without a dot or a signed exponent."""


_Loader.add_implicit_resolver("tag:yaml.org,2002:float", re.compile(r"^[-+]?[0-9][0-9_]*(\.[0-9_]*)?[eE][-+]?[0-9]+$"),
                              list("-+0123456789"))


def _construct_int(loader: _Loader, node: yaml.ScalarNode) -> int:
    """PyYAML's integer, or an error marked with the number's line and column where Python will not
    convert it (:func:`.numbers.long_integer_text`), instead of a ``ValueError`` that names nothing."""
    problem = long_integer_text(str(node.value))
    if problem:
        raise yaml.constructor.ConstructorError(None, None, problem, node.start_mark)
    return loader.construct_yaml_int(node)


_Loader.add_constructor("tag:yaml.org,2002:int", _construct_int)

CONFIG_FILE_LIMIT = 2**20
"""Most bytes a config file is read to (a config of every field takes about 2 kB)."""


def parse_yaml(text: str) -> Any:
    """The value YAML ``text`` holds, like ``yaml.safe_load``, except that ``1e-3`` and ``1e300`` are
    numbers (YAML 1.2) rather than the strings YAML 1.1, PyYAML's, makes of them (it wants
    ``1.0e-3``).

    Raises:
        yaml.YAMLError: malformed YAML. RecursionError: nested too deeply for the parser.
    """
    return yaml.load(text, Loader=_Loader)


def available_presets() -> list[str]:
    """Names of the presets (``sidar_torch/config/presets/<name>.yaml``), sorted."""
    return sorted(p.stem for p in PRESET_DIR.glob("*.yaml"))


def _parse(path: Path) -> dict[str, Any]:
    """The mapping a YAML file holds.

    Raises:
        FileNotFoundError: no such file.
        ValueError: not a regular file (a FIFO, a folder: refused before it is opened), larger than
            :data:`CONFIG_FILE_LIMIT` bytes, not UTF-8 text (a binary file), malformed YAML (the
            message names the file, line and column; an integer of more digits than Python reads
            too), nested too deeply to parse, or not a mapping; each message names the file.
    """
    data = read_regular(path, CONFIG_FILE_LIMIT, "config file ")
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as error:
        raise ValueError(f"config file {str(path)!r}: not UTF-8 text (byte {error.object[error.start]:#04x} at "
                         f"offset {error.start}); a config file is YAML text") from None
    try:
        data = parse_yaml(text)
    except RecursionError:  # the parser recurses once per level of nesting
        raise ValueError(f"config file {str(path)!r}: YAML nested too deeply to parse (a config is a mapping "
                         f"of fields to numbers, words and short lists)") from None
    except yaml.MarkedYAMLError as error:
        mark = error.problem_mark or error.context_mark
        where = f", line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        problem = " ".join(str(p) for p in (error.context, error.problem) if p)
        kind = "unreadable value" if isinstance(error, yaml.constructor.ConstructorError) else "malformed YAML"
        raise ValueError(f"config file {str(path)!r}{where}: {kind} ({problem})") from error
    except yaml.YAMLError as error:
        raise ValueError(f"config file {str(path)!r}: malformed YAML ({error})") from error
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ValueError(f"config file {str(path)!r}: expected a mapping of fields, got {type(data).__name__}")
    return data


def _yaml_path(source: str | os.PathLike) -> Path:
    """The file of a preset name or YAML path.

    Raises:
        ValueError: ``source`` is neither a preset's name nor a path ending in ``.yaml`` or ``.yml``.
    """
    path = Path(source)
    if path.suffix in (".yaml", ".yml"):
        return path
    presets = available_presets()
    if str(source) not in presets:
        raise ValueError(f"config {str(source)!r}: not a preset{did_you_mean(str(source), presets)} nor a YAML "
                         f"path; the presets are {', '.join(presets)}")
    return PRESET_DIR / f"{source}.yaml"


def _read_yaml(source: str | os.PathLike, seen: tuple[Path, ...] = ()) -> dict[str, tuple[Any, Path]]:
    """``{field: (value, file)}`` of a preset name or YAML path, with its ``base`` chain resolved
    (a file's values replace its base's), each value with the file it came from."""
    path = _yaml_path(source)
    if _resolved(path) in seen:
        raise ValueError(f"config {str(path)!r}: 'base' chain loops back to itself")
    data = _parse(path)
    base = data.pop("base", None)
    check_names(data, SidarConfig, f"field in {str(path)!r}:")
    fields = {name: (value, path) for name, value in data.items()}
    if base is None:
        return fields
    base_path = base if str(base) in available_presets() else path.parent / str(base)
    return {**_read_yaml(base_path, seen + (_resolved(path),)), **fields}


def _resolved(path: Path) -> Path:
    """``path`` absolute, its links followed as far as they go: a loop of links is left for the file's
    reading to refuse by name (``Path.resolve`` raises ``RuntimeError`` on Python 3.11)."""
    return Path(os.path.realpath(path))


def load_config(preset: str | os.PathLike | SidarConfig | None = "misaligned", **overrides: Any) -> SidarConfig:
    """Load a preset by name (see :func:`available_presets`) or a YAML path, and apply keyword overrides.

    Args:
        preset: preset name, path to a YAML file, an existing ``SidarConfig``, or ``None`` for the
            built-in defaults.
        **overrides: field values replacing the preset's, e.g. ``image_size=(384, 512)`` (``(H, W)``),
            ``n_lights=(0, 2)``; numbers may be NumPy or 0-d torch scalars.

    Raises:
        ValueError: unknown preset or field (with the closest names), a YAML file that is not a
            regular file (a FIFO, a loop of symbolic links), not UTF-8 text, malformed (naming the
            file and line) or nested too deeply, or a value of any type (a ``Fraction``, a
            ``Decimal``, an integer of 5000 digits, a bool, ...) that is not one the field takes or
            lies out of its range. The message names the field and where the value came from: the
            file (``config file '<path>': ...``) or the override (``override n_views='x': ...``); a
            rule between fields names the overrides when ``preset``'s values alone keep it
            (``overrides n_views=64 on config file '<path>': ...``), else ``preset``'s file. Nothing
            else: no ``TypeError`` or ``OverflowError`` for a wrong value.
        FileNotFoundError: a YAML path, or a ``base`` it names, does not exist.
    """
    check_names(overrides, SidarConfig, "override")
    if isinstance(preset, SidarConfig):
        fields = {f.name: (getattr(preset, f.name), None) for f in dataclasses.fields(preset)}
    else:
        fields = {} if preset is None else _read_yaml(preset)
    values = {name: value for name, (value, _) in fields.items()}
    for name, value in {**values, **overrides}.items():  # each value alone, naming where it came from
        try:
            check_field(SidarConfig.__dataclass_fields__[name], value)
        except ValueError as error:
            source = f"override {name}={shown(value)}" if name in overrides else f"config file {str(fields[name][1])!r}"
            raise ValueError(f"{source}: {error}") from None
    try:
        return SidarConfig(**{**values, **overrides})
    except ValueError as error:  # every value passed alone: a rule between fields
        raise ValueError(f"{_broken_by(preset, values, overrides)}: {error}") from None


def _broken_by(preset: str | os.PathLike | SidarConfig | None, values: dict[str, Any], overrides: dict[str, Any]) -> str:
    """Whom a rule between fields that ``values`` (``preset``'s) with ``overrides`` break is blamed on:
    ``"overrides a=1, b=2 on config file '<path>'"`` if ``preset``'s values alone keep every rule,
    else ``"config file '<path>'"`` (``" with overrides a=1"`` when there are some)."""
    source = ("the defaults" if preset is None else "the SidarConfig given" if isinstance(preset, SidarConfig)
              else f"config file {str(_yaml_path(preset))!r}")
    named = ", ".join(f"{name}={shown(value)}" for name, value in overrides.items())
    if not overrides:
        return source
    try:
        SidarConfig(**values)
    except ValueError:
        return f"{source} with overrides {named}"
    return f"overrides {named} on {source}"
