"""The manifest of an export: ``export.json`` (format, version, layout, seed, painting source,
config) and ``config.yaml`` (the config alone), written so that any interruption leaves a folder
the same command resumes, and read back checked field by field."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Callable

import yaml

from ..config import SidarConfig
from ..config.allowed import LENS_MODELS as LENS_MODEL_NAMES
from ..choices.lenses import NO_LENS
from ..sample import GEOMETRY_DTYPES, KEYS
from ..paintings import PaintingSource
from ..choices.outputs import OUTPUTS
from ..version import __version__
from .codecs import read_json
from .files import LOCK, is_own_temporary, read_inside, replace_file
from .layout import CONFIG, MANIFEST, Layout
from .layouts import LAYOUTS

FORMAT = "sidar_torch export"
FORMAT_VERSION = 1
RESUME_KEYS = ("format", "format_version", "package_version", "layout", "shard_size", "seed", "source", "config")
"""``export.json`` fields a rerun into an existing export must match."""

MANIFEST_LIMIT = 2**20
"""Most bytes an ``export.json`` is read to (a real one holds a config: a few kB; parsed JSON takes
up to about 9 times its bytes in Python objects: :data:`.limits.JSON_BYTES_PER_VIEW`)."""


OPTIONAL_KEYS = tuple(key for key in KEYS if key.name in OUTPUTS)
"""The optional outputs' sample keys (:data:`~sidar_torch.sample.KEYS` rows of ``choices.outputs.OUTPUTS``),
each turned on by a boolean config switch; ``lens`` (``lens_model``) and ``distortion_maps`` are in
``cameras.json`` or recomputed, and have no file of their own."""

def write_manifest(out: Path, seed: int, source: PaintingSource, config: dict[str, Any], layout: Layout) -> None:
    """Write ``export.json`` and ``config.yaml``, or check that a rerun matches the existing ones.

    ``export.json`` is written first, each file atomically: an interruption before it leaves no
    manifest (and only the export's own temporaries, which a rerun deletes), one after it an
    export that the rerun completes (it writes ``config.yaml`` when missing). Call it holding the lock.

    Raises:
        ValueError: ``out`` holds an export made with other settings, or holds files but no ``export.json``.
    """
    manifest = {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "package_version": __version__,
        "layout": layout.name,
        "shard_size": layout.shard_size,
        "seed": seed,
        "source": source.describe(),
        "config": config,
        "homographies": "H[i, j] maps view-i pixels to view-j pixels; Kornia pixels (centre of the top-left "
                        "pixel at (0, 0)); det = 1; float64",
        "masks": "255 where the painting is not visible (occluder or background), 0 where it is",
    }
    # What the files of each optional output it holds are (choices.outputs.OUTPUTS).
    manifest.update({key.name: OUTPUTS[key.name].description for key in OPTIONAL_KEYS if config.get(key.switch)})
    if (out / MANIFEST).exists():
        old = read_manifest(out)
        old["config"] = {**_added_fields(old["config"]), **old["config"]}
        differences = [_difference(key, old.get(key), manifest[key]) for key in RESUME_KEYS
                       if old.get(key) != manifest[key]]
        if differences:
            raise ValueError(f"out_dir: {str(out)!r} holds an export made with other settings "
                             f"({'; '.join(differences)}); export into a new folder or rerun with the recorded ones")
    else:
        foreign = sorted(p.name for p in out.iterdir() if p.name != LOCK and not is_own_temporary(p.name))
        if foreign:
            raise ValueError(f"out_dir: {str(out)!r} is not empty and holds no {MANIFEST} (found {foreign[:5]}); "
                             f"export into a new or empty folder")
        replace_file(out / MANIFEST, (json.dumps(manifest, indent=2) + "\n").encode())
    if not (out / CONFIG).exists():
        replace_file(out / CONFIG, yaml.safe_dump(manifest["config"], sort_keys=False).encode())


def _added_fields(config: dict[str, Any]) -> dict[str, Any]:
    """The config fields added to the package after ``config`` was recorded, at their defaults: what an
    export recorded before a field existed did (a field is added with the default that keeps what the
    package drew before it, as ``normals_output: false``), so a rerun resumes it."""
    return {name: value for name, value in SidarConfig().to_dict().items() if name not in config}


def _difference(key: str, there: Any, now: Any) -> str:
    """``"key: <there> there, <now> now"``, naming only the differing fields of two dicts."""
    if isinstance(there, dict) and isinstance(now, dict):
        fields = sorted(k for k in {*there, *now} if there.get(k, "(absent)") != now.get(k, "(absent)"))
        return "; ".join(f"{key}.{k}: {there.get(k, '(absent)')!r} there, {now.get(k, '(absent)')!r} now"
                         for k in fields)
    return f"{key}: {there!r} there, {now!r} now"


def read_manifest(path: Path) -> dict[str, Any]:
    """The ``export.json`` of the export at ``path``, checked to be of this format and version, with
    every field the reader and a rerun use of the expected type (see :func:`check_manifest`).

    Raises:
        ValueError: no ``export.json``, or one that is not a regular file of at most
            :data:`MANIFEST_LIMIT` bytes of UTF-8 JSON (an integer of more than 4300 digits
            included), or a field that is missing or wrong (the message names the file and the field).
    """
    manifest_path = path / MANIFEST
    if not manifest_path.exists():
        raise ValueError(f"{str(path)!r}: not a sidar_torch export (no {MANIFEST})")
    data = read_inside(manifest_path, path, MANIFEST_LIMIT)
    try:
        manifest = read_json(data)
    except ValueError as error:
        raise ValueError(f"{str(manifest_path)!r}: {error}") from None
    check_manifest(manifest, manifest_path)
    return manifest


def check_manifest(manifest: Any, where: Path) -> None:
    """Check the fields of a decoded ``export.json`` (``where`` names it in errors): the format and
    version, ``layout`` a key of :data:`.layouts.LAYOUTS` with a ``shard_size`` its row accepts
    (:meth:`.layout.Layout.from_record`), an integer ``seed``, a ``source`` and a ``config`` dict
    whose fields the reader uses (``image_size``, ``n_views``, the switches of :data:`OPTIONAL_KEYS`,
    ``geometry_dtype``) hold what they should.

    Raises:
        ValueError: naming ``where`` and the first wrong field.
    """
    def check(name: str, value: Any, ok: Callable[[Any], bool], expected: str) -> None:
        if not ok(value):
            raise ValueError(f"{str(where)!r}: field {name!r}: expected {expected}, got {value!r}")

    check("(top level)", manifest, lambda m: isinstance(m, dict), "a JSON object")
    if manifest.get("format") != FORMAT or manifest.get("format_version") != FORMAT_VERSION:
        raise ValueError(f"{str(where)!r}: expected format {FORMAT!r} version {FORMAT_VERSION}, "
                         f"got {manifest.get('format')!r} version {manifest.get('format_version')!r}")
    for key in RESUME_KEYS:
        check(key, key in manifest, bool, "a value (the field is missing)")
    check("layout", manifest["layout"], lambda v: isinstance(v, str) and v in LAYOUTS, f"one of {list(LAYOUTS)}")
    try:
        LAYOUTS[manifest["layout"]].from_record(manifest["shard_size"])
    except ValueError as error:
        raise ValueError(f"{str(where)!r}: {error}") from None
    check("seed", manifest["seed"], lambda v: _is_int(v, 0), "an integer >= 0")
    check("source", manifest["source"], lambda v: isinstance(v, dict), "a JSON object")
    config = manifest["config"]
    check("config", config, lambda v: isinstance(v, dict), "a JSON object")
    check("config.image_size", config.get("image_size"),
          lambda v: isinstance(v, list) and len(v) == 2 and all(_is_int(n, 1) for n in v), "[H, W], integers >= 1")
    check("config.n_views", config.get("n_views"), lambda v: _is_int(v, 1), "an integer >= 1")
    for switch in (*(key.switch for key in OPTIONAL_KEYS), "distortion_map_output"):
        check(f"config.{switch}", config.get(switch, False), lambda v: isinstance(v, bool), "true or false")
    for name, names, default in (("lens_model", LENS_MODEL_NAMES, NO_LENS),
                                 ("geometry_dtype", GEOMETRY_DTYPES, "float32")):
        check(f"config.{name}", config.get(name, default), lambda v: isinstance(v, str) and v in names,
              f"one of {list(names)}")


def _is_int(value: Any, minimum: int) -> bool:
    """True for a JSON integer (not a bool) ``>= minimum``."""
    return type(value) is int and value >= minimum
