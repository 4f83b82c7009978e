"""``ExportedDataset``: a set written by :func:`sidar_torch.export_dataset`, read back as samples."""

from __future__ import annotations

import os
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
from torch.utils.data import Dataset

from . import folders, shards
from .layout import decode, read_manifest, sample_from_entries


def _read_file(folder: Path, name: str) -> Any:
    return decode(name, (folder / name).read_bytes())


def _read_entry(entries: dict[str, tuple[Path, int, int]], name: str) -> Any:
    return decode(name, shards.read_entry(entries, name))


class ExportedDataset(Dataset):
    """A set written by :func:`export_dataset`, read back as :class:`SidarDataset` samples.

    A map-style dataset: item ``k`` is the ``k``-th exported sequence in index order (``indices[k]``
    is its dataset index). Each item is rebuilt as the :class:`sidar_torch.sample.SampleArrays`
    the export wrote and converted by the same :meth:`~sidar_torch.sample.SampleArrays.to_tensors`
    as :meth:`SidarDataset.sample`, so for the same seed, config and source it is that sample bit
    for bit (keys, shapes, dtypes: the table :data:`sidar_torch.sample.KEYS`; geometry in the
    recorded config's ``geometry_dtype``, from the float64 files). Reads both layouts; works in
    DataLoader workers.

    Args:
        path: the export folder.

    Attributes:
        config: the config fields the set was rendered with, as recorded (a dict, so that sets
            written by other versions of the package load; ``SidarConfig(**config)`` rebuilds it
            when the fields match this version's).
        seed: its seed.
        layout: ``"folders"`` or ``"shards"``.
        indices: dataset index of each item, ascending.

    Raises:
        FileNotFoundError: ``path`` does not exist.
        ValueError: ``path`` holds no export (no ``export.json``) or one of another format.
    """

    def __init__(self, path: str | os.PathLike):
        self.path = Path(path)
        if not self.path.is_dir():
            raise FileNotFoundError(f"path: no export folder at {str(self.path)!r}")
        manifest = read_manifest(self.path)
        self.config: dict[str, Any] = manifest["config"]
        self.seed: int = manifest["seed"]
        self.layout: str = manifest["layout"]
        # Per item: its index and where its entries are: a folder, or {name: (shard, offset, size)}.
        self._items = folders.sequences(self.path) if self.layout == "folders" else shards.sequences(self.path)
        self.indices = [index for index, _ in self._items]

    def __len__(self) -> int:
        return len(self._items)

    def __getitem__(self, k: int) -> dict[str, Any]:
        """Item ``k`` (``0 <= k < len(self)``, negative counts from the end) as a sample dict."""
        if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or not -len(self) <= k < len(self):
            raise IndexError(f"index {k!r}: expected an integer in [{-len(self)}, {len(self)})")
        index, where = self._items[k]
        if isinstance(where, Path):
            read, layout = partial(_read_file, where), folders
        else:
            read, layout = partial(_read_entry, where), shards
        arrays = sample_from_entries(read, index, self.config, partial(layout.read_homographies, read))
        return arrays.to_tensors(self.config.get("geometry_dtype", "float32"))
