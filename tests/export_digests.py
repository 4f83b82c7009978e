"""Stored SHA-256 digests of every file of a folder export and a shard export, recorded with the
code of ``main`` before the export was split into ``sidar_torch/io/`` (re-recorded when a config default
changed, which changes the manifests): a guard that the writers change no byte.

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


HERE = Path(__file__).resolve().parent
STORE = HERE / "data" / "export_digests.json"
CONFIG = dict(image_size=(24, 32), n_views=3, shadow_map_size=256, opacity_output=True, n_occluders=(2, 2))
SEED, START, COUNT, SHARD_SIZE = 5, 1, 3, 2
LOCK = ".export.lock"
def digest(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def tree_digests(root: Path) -> dict[str, str]:
    """``{path: sha256}`` of every file under ``root`` (the lock file aside) and, for a tar, ``{"<tar>:<entry>": sha256}`` of each entry, so
    that a mismatch names the entry."""
    digests = {}
    for path in sorted(root.rglob("*")):
        if not path.is_file() or path.name == LOCK:
            continue
        name = str(path.relative_to(root))
        data = path.read_bytes()
        digests[name] = digest(data)
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
