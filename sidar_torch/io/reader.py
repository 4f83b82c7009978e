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
from .layout import MANIFEST, sequence_name, shown_names
from .limits import check_recorded_sizes, entry_size_limit
from ..sample import GEOMETRY_DTYPES
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
    :mod:`.paper`): their ``H_i_j.mat`` texts hold all 17 digits of a float64, which
    ``geometry_dtype="float64"`` keeps (in float32, the default there, ``H[4, 3]`` of the paper's
    sequence 5 sends pixel (511, 383), near the horizon, 15.7 px from where the float64 one does).

    Every number read is checked, not only its type and shape: cameras (finite pinhole ``K``, a
    rotation ``R``, finite ``t``, a lens the config's bounds allow, :func:`.entries.read_cameras`) and
    homographies (finite, invertible whatever their scale, :func:`.entries.checked_homography`), so no
    file makes an item hold NaN or infinity (but the unknown cameras of the paper's own sequences,
    which are NaN).

    Args:
        path: the export folder.
        geometry_dtype: ``"float32"`` or ``"float64"``, the dtype of the items' ``homographies``, ``K``,
            ``R`` and ``t`` (from the float64 files); None (the default): the recorded config's
            ``geometry_dtype`` (float32 where none is recorded, as for the paper's own sequences).

    Attributes:
        config: the config fields the set was rendered with, as recorded (a dict, so that sets
            written by other versions of the package load; ``SidarConfig(**config)`` rebuilds it
            when the fields match this version's).
        seed: its seed (``None`` for the paper's own sequences).
        layout: a name of :data:`.layouts.LAYOUTS`: ``"folders"``, ``"shards"`` or ``"paper"``.
        indices: dataset index of each item, ascending.
        geometry_dtype: the dtype of the items' geometry, ``"float32"`` or ``"float64"``.

    Raises:
        FileNotFoundError: ``path`` does not exist.
        ValueError: ``path`` holds no export (no ``export.json``), one of another format, a
            manifest with a missing or wrong field or sizes beyond the bounds, no sequence of its
            layout, or a damaged shard (each message names the file); ``geometry_dtype`` not one of
            the two; an item, a missing or malformed file of its sequence (named).
    """

    def __init__(self, path: str | os.PathLike, geometry_dtype: str | None = None):
        if geometry_dtype is not None and (not isinstance(geometry_dtype, str) or geometry_dtype not in GEOMETRY_DTYPES):
            raise ValueError(f"geometry_dtype: expected one of {list(GEOMETRY_DTYPES)} or None (the recorded "
                             f"config's), got {geometry_dtype!r}")
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
        if not self._items:
            raise ValueError(f"{str(recorded)!r}: records layout {self.layout!r}, but {str(self.path)!r} holds no "
                             f"sequence of that layout (found {_first_names(self.path)})")
        self.indices = [index for index, _ in self._items]
        self.geometry_dtype: str = geometry_dtype or self.config.get("geometry_dtype", "float32")

    def __len__(self) -> int:
        return len(self._items)

    def __getitem__(self, k: int) -> dict[str, Any]:
        """Item ``k`` (``0 <= k < len(self)``, negative counts from the end) as a sample dict."""
        if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or not -len(self) <= k < len(self):
            raise IndexError(f"index {k!r}: expected an integer in [{-len(self)}, {len(self)})")
        index, where = self._items[k]
        try:
            read = partial(self._read, index, where)
            arrays = sample_from_entries(read, index, self.config, partial(self._layout.read_homographies, read),
                                         self._layout.read_cameras)
        except FileNotFoundError as error:
            raise ValueError(f"sequence {sequence_name(index)} of {str(self.path)!r}: a file is missing: {error}") from None
        return arrays.to_tensors(self.geometry_dtype)

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



def _first_names(path: Path) -> str:
    """The names in the folder ``path``, sorted, as :func:`shown_names` shows them."""
    return shown_names(sorted(p.name for p in path.iterdir()))
