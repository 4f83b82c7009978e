"""Stored records of every file of a folder export and a shard export: a guard that the writers
change no byte.

``python tests/export_digests.py --write`` records them (only in a commit whose purpose is to
change exported files, saying so); ``tests/io/test_export.py`` compares. As in ``stored_digests.py``:
PNGs by SHA-256 digest, compared only where the GL renderer string is the recorded one; files of
geometry (``H_<i>_<j>.mat``, ``homographies.npy``, ``cameras.json``) by their decoded numbers within
``recorded.py``'s tolerances; a shard by the names of its entries (each entry is recorded on its
own); every other file (manifests) by digest, everywhere.
"""

from __future__ import annotations

import io
import json
import sys
import tarfile
import tempfile
from pathlib import Path
from typing import Iterator


HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from recorded import digest, environment, geometry_record  # noqa: E402

STORE = HERE / "data" / "export_digests.json"
CONFIG = dict(image_size=(24, 32), n_views=3, shadow_map_size=256, opacity_output=True, n_occluders=(2, 2))
SEED, START, COUNT, SHARD_SIZE = 5, 1, 3, 2
LOCK = ".export.lock"
GEOMETRY_FILES = (".mat", ".npy", "cameras.json")


def file_record(name: str, data: bytes) -> dict:
    """``{"fields": {field: geometry_record}}`` for a file of geometry (a JSON file's text fields
    as ``{"text": ...}``), else ``{"sha256": ...}``."""
    from sidar_torch.io.codecs import decode

    if not name.endswith(GEOMETRY_FILES):
        return {"sha256": digest(data)}
    value = decode(name, data)
    fields = value.items() if isinstance(value, dict) else [("values", value)]
    return {"fields": {field: {"text": v} if isinstance(v, str) else geometry_record(v) for field, v in fields}}


def tree_files(root: Path) -> Iterator[tuple[str, bytes]]:
    """``(name, bytes)`` of every file under ``root`` (the lock file aside) and, after a tar, of each
    of its entries as ``"<tar>:<entry>"``, so that a mismatch names the entry."""
    for path in sorted(root.rglob("*")):
        if not path.is_file() or path.name == LOCK:
            continue
        name = str(path.relative_to(root))
        yield name, path.read_bytes()
        if path.suffix == ".tar":
            with tarfile.open(path) as tar:
                for member in tar.getmembers():
                    yield f"{name}:{member.name}", tar.extractfile(member).read()


def tree_digests(root: Path) -> dict[str, str]:
    """``{name: sha256}`` of :func:`tree_files`: two exports made here are byte-identical when these are equal."""
    return {name: digest(data) for name, data in tree_files(root)}


def tree_records(root: Path) -> dict[str, dict]:
    """``{name: file_record}`` of :func:`tree_files`, a tar recorded as the names of its entries."""
    records = {}
    for name, data in tree_files(root):
        if name.endswith(".tar"):
            with tarfile.open(fileobj=io.BytesIO(data)) as tar:
                records[name] = {"members": tar.getnames()}
        else:
            records[name] = file_record(name, data)
    return records


def current_records() -> dict[str, dict[str, dict]]:
    """``{"folders": {...}, "shards": {...}}``: digests of both layouts of the same sequences."""
    from sidar_torch import SidarDataset, export_dataset, load_config

    dataset = SidarDataset(config=load_config("misaligned", **CONFIG), seed=SEED)
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        for layout, shards in (("folders", None), ("shards", SHARD_SIZE)):
            export_dataset(dataset, Path(tmp) / layout, count=COUNT, start=START, shard_size=shards, progress=False)
            out[layout] = tree_records(Path(tmp) / layout)
    return out


def is_pixel_file(name: str) -> bool:
    """PNGs depend on the rasteriser."""
    return name.endswith(".png")


if __name__ == "__main__":
    if sys.argv[1:] != ["--write"]:
        raise SystemExit("usage: python tests/export_digests.py --write")
    records = current_records()
    STORE.write_text(json.dumps({"recorded_with": environment(), "exports": records}, indent=1, sort_keys=True) + "\n")
    print(f"wrote {STORE} ({sum(map(len, records.values()))} records)")
