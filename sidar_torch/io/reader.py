"""``ExportedDataset``: a set written by :func:`sidar_torch.export_dataset`, read back as samples."""

from __future__ import annotations

import os
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
from torch.utils.data import Dataset

from .codecs import decode, png_size
from .entries import sample_from_entries
from .layouts import recorded_layout
from .layout import MANIFEST
from .manifest import read_manifest
from .paper import paper_manifest


def entry_size_limit(config: dict[str, Any]) -> int:
    """Most bytes one file of a sequence rendered with ``config`` can hold, with a wide margin: four
    times a view's raw RGB pixels (a PNG adds a few bytes per row and per 32 kB), plus 128 bytes per
    pair of views (``homographies.npy`` holds 72), plus 1 MiB (``cameras.json``, headers)."""
    height, width = config["image_size"]
    return 4 * height * width * 3 + 128 * config["n_views"] ** 2 + 2**20


class ExportedDataset(Dataset):
    """A set written by :func:`export_dataset`, read back as :class:`SidarDataset` samples.

    A map-style dataset: item ``k`` is the ``k``-th exported sequence in index order (``indices[k]``
    is its dataset index). Each item is rebuilt as the :class:`sidar_torch.sample.SampleArrays`
    the export wrote and converted by the same :meth:`~sidar_torch.sample.SampleArrays.to_tensors`
    as :meth:`SidarDataset.sample`, so for the same seed, config and source it is that sample bit
    for bit (keys, shapes, dtypes: the table :data:`sidar_torch.sample.KEYS`; geometry in the
    recorded config's ``geometry_dtype``, from the float64 files). Reads every layout of
    :data:`.layouts.LAYOUTS` through its interface; works in DataLoader workers.

    Only regular files inside ``path`` are read (a link out of it, a FIFO or a device is an error
    naming it), each of at most :func:`entry_size_limit` bytes, and a PNG only if its header gives
    the recorded ``image_size``.

    Also reads a folder of the SIDAR paper's own sequences (no ``export.json``; what is inferred:
    :mod:`.paper`).

    Args:
        path: the export folder.

    Attributes:
        config: the config fields the set was rendered with, as recorded (a dict, so that sets
            written by other versions of the package load; ``SidarConfig(**config)`` rebuilds it
            when the fields match this version's).
        seed: its seed (``None`` for the paper's own sequences).
        layout: a name of :data:`.layouts.LAYOUTS`: ``"folders"``, ``"shards"`` or ``"paper"``.
        indices: dataset index of each item, ascending.

    Raises:
        FileNotFoundError: ``path`` does not exist.
        ValueError: ``path`` holds no export (no ``export.json``), one of another format, a
            manifest with a missing or wrong field, or a damaged shard (each message names the file).
    """

    def __init__(self, path: str | os.PathLike):
        self.path = Path(path)
        if not self.path.is_dir():
            raise FileNotFoundError(f"path: no export folder at {str(self.path)!r}")
        # No export.json: the SIDAR paper's own sequence folders, if that is what it holds.
        manifest = read_manifest(self.path) if (self.path / MANIFEST).exists() else paper_manifest(self.path)
        self.config: dict[str, Any] = manifest["config"]
        self.seed: int = manifest["seed"]
        self.layout: str = manifest["layout"]
        self._layout = recorded_layout(manifest)
        # Per item: its index and where the layout finds its entries (a folder, a shard's offsets).
        self._items = self._layout.sequences(self.path)
        self.indices = [index for index, _ in self._items]

    def __len__(self) -> int:
        return len(self._items)

    def __getitem__(self, k: int) -> dict[str, Any]:
        """Item ``k`` (``0 <= k < len(self)``, negative counts from the end) as a sample dict."""
        if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or not -len(self) <= k < len(self):
            raise IndexError(f"index {k!r}: expected an integer in [{-len(self)}, {len(self)})")
        index, where = self._items[k]
        read = partial(self._read, where)
        arrays = sample_from_entries(read, index, self.config, partial(self._layout.read_homographies, read))
        return arrays.to_tensors(self.config.get("geometry_dtype", "float32"))

    def _read(self, where: Any, name: str) -> Any:
        """Entry ``name`` of the sequence the layout finds at ``where``, decoded."""
        path, data = self._layout.read(self.path, where, name, entry_size_limit(self.config))
        return self._decode(path, name, data)

    def _decode(self, where: Path, name: str, data: bytes) -> Any:
        """``data`` decoded by ``name``'s extension; a PNG only if its header gives the recorded size."""
        if name.endswith(".png"):
            expected = tuple(self.config["image_size"])
            if png_size(data) != expected:
                raise ValueError(f"{str(where)!r}: {name} is not a PNG of {expected[0]} x {expected[1]} pixels "
                                 f"(H x W, the recorded image_size): its header says {png_size(data)}")
        return decode(name, data)
