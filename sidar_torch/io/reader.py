"""``ExportedDataset``: a set written by :func:`sidar_torch.export_dataset`, read back as samples."""

from __future__ import annotations

import os
from functools import partial
from pathlib import Path
from typing import Any, Callable

import numpy as np
from torch.utils.data import Dataset

from .codecs import decode
from .entries import sample_from_entries
from .layouts import recorded_layout
from .layout import MANIFEST, sequence_name
from .limits import check_recorded_sizes, entry_size_limit
from .manifest import read_manifest
from .paper import paper_manifest


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
    naming it), each of at most :func:`.limits.entry_size_limit` bytes. The recorded ``image_size``
    and ``n_views`` are checked against the package's bounds (:func:`.limits.check_recorded_sizes`)
    before any sequence is read, and each file against them before anything of its size is
    decoded, inflated or allocated (a PNG's header, ``cameras.json``'s cameras, a ``.npy`` header,
    a ``.mat``'s variable): a malformed file is a ``ValueError`` naming it (and a shard's entry).

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
            manifest with a missing or wrong field or sizes beyond the bounds, or a damaged shard
            (each message names the file); an item, a malformed file of its sequence.
    """

    def __init__(self, path: str | os.PathLike):
        self.path = Path(path)
        if not self.path.is_dir():
            raise FileNotFoundError(f"path: no export folder at {str(self.path)!r}")
        # No export.json: the SIDAR paper's own sequence folders, if that is what it holds.
        recorded = self.path / MANIFEST
        manifest = read_manifest(self.path) if recorded.exists() else paper_manifest(self.path)
        check_recorded_sizes(manifest["config"], recorded if recorded.exists() else self.path)
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
        read = partial(self._read, index, where)
        arrays = sample_from_entries(read, index, self.config, partial(self._layout.read_homographies, read))
        return arrays.to_tensors(self.config.get("geometry_dtype", "float32"))

    def _read(self, index: int, where: Any, name: str, shape: tuple[int, ...] | None = None,
              check: Callable[[Any], Any] | None = None, dtype: Any = None) -> Any:
        """Entry ``name`` of sequence ``index``, which the layout finds at ``where``, decoded and
        checked to be of ``shape`` and ``dtype`` (:func:`.codecs.decode`) and by ``check`` (value -> value).

        Raises:
            FileNotFoundError: no such entry.
            ValueError: a malformed entry, its file (and a shard's entry) named.
        """
        path, data = self._layout.read(self.path, where, name, entry_size_limit(self.config, name))
        try:
            value = decode(name, data, shape, dtype)
            return value if check is None else check(value)
        except ValueError as error:
            entry = "" if path.name == name else f": entry {sequence_name(index)}.{name}"
            raise ValueError(f"{str(path)!r}{entry}: {error}") from None
