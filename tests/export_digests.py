"""Stored SHA-256 digests of every file of a folder export and a shard export, recorded with the
code of ``main`` before the export was split into ``sidar_torch/io/``: a guard that the writers
change no byte.

``python tests/export_digests.py --write`` records them (only in a commit whose purpose is to
change exported files, saying so); ``tests/test_export_digests.py`` compares. As in
``stored_digests.py``, files holding pixels (PNGs, and the shards, which hold PNGs) are compared
only where the GL renderer string is the one the digests were recorded on.
"""

from __future__ import annotations

import hashlib
import json
import sys
import tarfile
import tempfile
from pathlib import Path

import yaml

HERE = Path(__file__).resolve().parent
STORE = HERE / "data" / "export_digests.json"
CONFIG = dict(image_size=(24, 32), n_views=3, shadow_map_size=256, opacity_output=True, n_occluders=(2, 2))
SEED, START, COUNT, SHARD_SIZE = 5, 1, 3, 2
LOCK = ".export.lock"
NEW_CONFIG_FIELDS = {"geometry_dtype": "float32"}
"""Config fields added since the digests were recorded, with the value this export must record:
checked, then removed from ``export.json`` and ``config.yaml`` (re-serialised as the writer does)
before digesting, so the rest of both files is compared byte for byte."""


def digest(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def without_new_fields(name: str, data: bytes) -> bytes:
    """``export.json`` or ``config.yaml`` as the export of ``main`` wrote it: :data:`NEW_CONFIG_FIELDS` removed."""
    if name == "config.yaml":
        config = yaml.safe_load(data)
        _remove_new_fields(config)
        return yaml.safe_dump(config, sort_keys=False).encode()
    manifest = json.loads(data)
    _remove_new_fields(manifest["config"])
    return (json.dumps(manifest, indent=2) + "\n").encode()


def _remove_new_fields(config: dict) -> None:
    for field, value in NEW_CONFIG_FIELDS.items():
        if field in config:
            assert config.pop(field) == value, f"config.{field}: expected {value!r}"


def tree_digests(root: Path) -> dict[str, str]:
    """``{path: sha256}`` of every file under ``root`` (the lock file aside; the manifests without
    :data:`NEW_CONFIG_FIELDS`) and, for a tar, ``{"<tar>:<entry>": sha256}`` of each entry, so
    that a mismatch names the entry."""
    digests = {}
    for path in sorted(root.rglob("*")):
        if not path.is_file() or path.name == LOCK:
            continue
        name = str(path.relative_to(root))
        data = path.read_bytes()
        digests[name] = digest(without_new_fields(name, data) if name in ("export.json", "config.yaml") else data)
        if path.suffix == ".tar":
            with tarfile.open(path) as tar:
                for member in tar.getmembers():
                    digests[f"{name}:{member.name}"] = digest(tar.extractfile(member).read())
    return digests


def current_digests() -> dict[str, dict[str, str]]:
    """``{"folders": {...}, "shards": {...}}``: digests of both layouts of the same sequences."""
    from sidar_torch import SidarDataset, export_dataset, load_config

    dataset = SidarDataset(config=load_config("misaligned", **CONFIG), seed=SEED)
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        for layout, shards in (("folders", None), ("shards", SHARD_SIZE)):
            export_dataset(dataset, Path(tmp) / layout, count=COUNT, start=START, shards=shards, progress=False)
            out[layout] = tree_digests(Path(tmp) / layout)
    return out


def is_pixel_file(name: str) -> bool:
    """PNGs and shards (which hold PNGs) depend on the rasteriser."""
    return name.endswith((".png", ".tar"))


if __name__ == "__main__":
    if sys.argv[1:] != ["--write"]:
        raise SystemExit("usage: python tests/export_digests.py --write")
    from stored_digests import gl_renderer

    digests = current_digests()
    STORE.write_text(json.dumps({"gl_renderer": gl_renderer(), "exports": digests}, indent=1, sort_keys=True) + "\n")
    print(f"wrote {STORE} ({sum(map(len, digests.values()))} digests)")
