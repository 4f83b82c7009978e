"""What the export layouts share: the interface each answers (:class:`Layout`, its write unit
:class:`WriteUnit`) and the names an export writes at its top. A sequence's entries are
:mod:`.entries`, their bytes :mod:`.codecs`, the files :mod:`.files`, the manifest :mod:`.manifest`,
the table of layouts :mod:`.layouts`.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, ClassVar, Protocol, runtime_checkable

import numpy as np

from ..sample import SampleArrays

MANIFEST = "export.json"
CONFIG = "config.yaml"
SEQUENCE_NAME = re.compile(r"^\d{6,}$")
SHARD_NAME = re.compile(r"^shard-(\d{5,})\.tar$")


@dataclass(frozen=True)
class WriteUnit:
    """What one write of a layout makes whole or not at all: a sequence folder, a tar shard.

    Attributes:
        number: the unit's number in its layout (the sequence's index for a folder, ``k`` for shard ``k``).
        indices: the dataset indices this write adds to the unit, ascending (a damaged shard that
            only needs rewriting has none).
    """

    number: int
    indices: tuple[int, ...]


@runtime_checkable
class Layout(Protocol):
    """The questions every export layout answers (one class per layout: :class:`.folders.FolderLayout`,
    :class:`.shards.ShardLayout`; the table :data:`.layouts.LAYOUTS` keys them by ``name``).

    Export, the reader and Ray look the layout up once (:func:`.layouts.layout_for`,
    :func:`.layouts.recorded_layout`) and ask it; they never ask which layout it is.

    Attributes:
        name: the manifest's ``layout`` (``"folders"``, ``"shards"``).
        shard_size: the manifest's ``shard_size`` (``None`` for folders).
        units_per_task: most write units one Ray export task writes.
    """

    name: ClassVar[str]
    units_per_task: ClassVar[int]

    @property
    def shard_size(self) -> int | None: ...

    @classmethod
    def from_record(cls, shard_size: Any) -> Layout:
        """The layout of an ``export.json`` with this ``layout`` and ``shard_size``; ``ValueError``
        (``"field 'shard_size': expected ..., got ..."``) if the layout takes no such ``shard_size``."""

    def present(self, out: Path, wanted: range) -> tuple[set[int], frozenset[int]]:
        """``(held, damaged)``: the indices of ``wanted`` (non-empty) that ``out`` holds whole, and
        the numbers of the damaged units among theirs (to rewrite)."""

    def groups(self, missing: list[int], damaged: frozenset[int]) -> list[WriteUnit]:
        """The write units that add the ``missing`` indices (ascending) or rewrite the ``damaged``
        units, ascending by number."""

    def write(self, out: Path, unit: WriteUnit, render: Callable[[int], SampleArrays],
              written: Callable[[], None]) -> None:
        """Write ``unit`` into ``out`` atomically: each of ``unit.indices`` that ``out`` does not hold
        yet is ``render(index)``-ed (ascending) and added, ``written()`` called after each; what
        ``out`` holds is kept (so a retry after a killed attempt writes only what is missing)."""

    def sequences(self, out: Path) -> list[tuple[int, Any]]:
        """``(index, where)`` of every sequence in ``out``, ascending; ``where`` is what :meth:`read` takes.

        Raises:
            ValueError: a damaged unit (the message names its file).
        """

    def read(self, out: Path, where: Any, name: str, limit: int) -> tuple[Path, bytes]:
        """``(file, bytes)`` of entry ``name`` of the sequence at ``where``: the file it is in (for
        messages) and its bytes, at most ``limit`` of them, read only inside ``out``.

        Raises:
            FileNotFoundError: the sequence has no entry ``name``.
            ValueError: the entry is larger than ``limit`` bytes or not a regular file inside ``out``.
        """

    def read_cameras(self, read: Callable[..., Any], config: dict[str, Any]) -> dict[str, np.ndarray]:
        """The cameras of a sequence recorded with ``config`` (``read`` as for :meth:`read_homographies`),
        checked (:func:`.entries.read_cameras`): ``{name: float64 array}`` for each key of
        :data:`.entries.CAMERA_KEYS` the config has."""

    def read_homographies(self, read: Callable[..., Any], n_views: int) -> np.ndarray:
        """``(V, V, 3, 3)`` float64 homographies of a sequence from its decoded entries (``read``:
        entry name and, optionally, the array's expected shape and a check (value -> value) ->
        value, checked to be of that shape before it is made: see :func:`.codecs.decode`), the
        identity on the diagonal, each checked (:func:`.entries.checked_homography`)."""


def sequence_name(index: int) -> str:
    """The name of sequence ``index``: its 6-digit (or longer) index."""
    return f"{index:06d}"


def is_export_name(name: str) -> bool:
    """True for a name an export writes at its top: a sequence folder, a shard, the manifest or the config."""
    return bool(SEQUENCE_NAME.match(name) or SHARD_NAME.match(name)) or name in (MANIFEST, CONFIG)


SHOWN_NAMES = 5
"""Most names an error message lists of a folder's or a sequence's contents (it gives their count too)."""


def shown_names(names: list[str]) -> str:
    """``"N: 'a', 'b', ..."``: the count of ``names`` and the first :data:`SHOWN_NAMES` of them, in order."""
    more = ", ..." if len(names) > SHOWN_NAMES else ""
    return f"{len(names)}: {', '.join(map(repr, names[:SHOWN_NAMES]))}{more}"
