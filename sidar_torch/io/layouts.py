"""The table of export layouts: :data:`LAYOUTS`, keyed by the manifest's ``layout`` name.

Every layout answers the questions of :class:`~.layout.Layout` (which sequences are here, how
missing ones group into write units, write a unit, list the sequences, read an entry); export,
the reader and Ray look the layout up here once and ask it. A new layout is one module with its
class and one row here.
"""

from __future__ import annotations

from typing import Any

from ..config import as_int
from .folders import FolderLayout
from .layout import Layout
from .paper import PaperLayout
from .shards import ShardLayout

LAYOUTS: dict[str, type[Layout]] = {layout.name: layout for layout in (FolderLayout, ShardLayout, PaperLayout)}
"""Manifest ``layout`` name -> the class answering :class:`~.layout.Layout` for it."""


def layout_for(shard_size: Any, name: str | None = None) -> Layout:
    """The layout :func:`~.export.export_dataset`'s ``shard_size`` and ``layout`` arguments ask for:
    ``name`` a row of :data:`LAYOUTS` (``"paper"``: the paper's files); without it, ``shard_size``
    ``None`` one folder per sequence, ``N >= 1`` tar shards of ``N`` sequences.

    Raises:
        ValueError, TypeError: ``shard_size`` is neither ``None`` nor an integer ``>= 1`` (see
            :func:`as_int`), ``name`` is not a row, or its row takes no such ``shard_size``.
    """
    if name is not None:
        if name not in LAYOUTS:
            raise ValueError(f"layout: expected one of {sorted(LAYOUTS)}, got {name!r}")
        return LAYOUTS[name].from_record(shard_size if shard_size is None else as_int("shard_size", shard_size, 1))
    if shard_size is None:  # the one place the argument picks a row of the table
        return FolderLayout()
    return ShardLayout(as_int("shard_size", shard_size, 1))


def recorded_layout(manifest: dict[str, Any]) -> Layout:
    """The layout an ``export.json`` (checked by :func:`.manifest.check_manifest`) records: the
    table's row for its ``layout``, with its ``shard_size``."""
    return LAYOUTS[manifest["layout"]].from_record(manifest["shard_size"])
