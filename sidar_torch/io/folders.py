"""The folder layout: one folder per sequence with the SIDAR paper's file names, PNGs and one MATLAB
file per ordered pair of views (the paper's own layout, its homographies as text in its pixels, is
:mod:`.paper`'s).

::

    000007/            the sequence of dataset index 7 (at least 6 digits)
      0.png .. <V-1>.png   the views, 8-bit RGB; view 0 is the reference camera
      0-m.png ..           the masks, 8-bit grey: 255 where the painting is not visible, else 0
      0-o.png, 0-n.npy ..  the optional outputs switched on (``opacity_output``, ``normals_output``, ...): one
                           file per view each, named and described by its row of ``choices.outputs.OUTPUTS``
                           (``entry``, ``description``; ``export.json`` lists those of the set)
      gt.png               the label (the painting in view 0's frame, unlit, unoccluded)
      H_<i>_<j>.mat        homographies[i, j] for every ordered pair i != j: variable ``H``, 3 x 3 float64
      cameras.json         index, image_size [H, W], K, R, t per view (float64), homography_error

The paper writes one file per unordered pair; both directions are written here so that
``H[j, i]`` is the dataset's own fit (within float64 round-off of ``inv(H[i, j])``, not equal to
it bit for bit). ``H[i, i]`` is the identity and not written.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, ClassVar

import numpy as np

from ..sample import SampleArrays
from .files import read_inside, remove_stale_temporary, replace_folder
from .codecs import encode
from .entries import cameras_entry, checked_homography, sample_entries
from .layout import SEQUENCE_NAME, WriteUnit, sequence_name


def homography_entry(i: int, j: int) -> str:
    """The file of the homography from view ``i`` to view ``j`` (the paper's name; its own layout
    writes it for ``i < j`` only)."""
    return f"H_{i}_{j}.mat"


def entries(arrays: SampleArrays) -> dict[str, Any]:
    """A sequence's files by name: the shared entries, then ``H_<i>_<j>.mat`` for every ordered pair."""
    files = sample_entries(arrays)
    for i, j in itertools.permutations(range(len(arrays.images)), 2):
        files[homography_entry(i, j)] = arrays.homographies[i, j]
    return files


@dataclass(frozen=True)
class FolderLayout:
    """The folder layout as a :class:`~.layout.Layout`: one write unit per sequence folder."""

    name: ClassVar[str] = "folders"
    units_per_task: ClassVar[int] = 16
    """Sequences one Ray export task writes at most: a task costs Ray a few milliseconds, a
    sequence 0.1-1 s (fewer per task when there are few per CPU, so that no CPU idles at the end)."""

    @property
    def shard_size(self) -> None:
        """Always ``None``: the manifest's ``shard_size`` of a folder export."""
        return None

    @classmethod
    def from_record(cls, shard_size: Any) -> FolderLayout:
        """The layout of a manifest whose ``shard_size`` is ``shard_size``; ``ValueError`` unless it is ``None``."""
        if shard_size is not None:
            raise ValueError(f"field 'shard_size': expected null for the folder layout, got {shard_size!r}")
        return cls()

    def present(self, out: Path, wanted: range) -> tuple[set[int], frozenset[int]]:
        """``(held, frozenset())``: the indices of ``wanted`` whose folder ``out`` holds; a folder is
        never damaged (it is moved into place whole)."""
        wanted = set(wanted)
        held = {int(p.name) for p in out.iterdir() if SEQUENCE_NAME.match(p.name) and int(p.name) in wanted}
        return held, frozenset()

    def groups(self, missing: list[int], damaged: frozenset[int]) -> list[WriteUnit]:
        """One unit per missing index (``damaged`` is always empty here)."""
        return [WriteUnit(index, (index,)) for index in missing]

    def write(self, out: Path, unit: WriteUnit, render: Callable[[int], SampleArrays],
              written: Callable[[], None]) -> None:
        """Write the folder of ``unit.indices`` (one index) unless ``out`` holds it, removing the
        temporary of an attempt that died first (see :meth:`.layout.Layout.write`)."""
        for index in unit.indices:
            path = out / sequence_name(index)
            if path.is_dir():
                continue
            remove_stale_temporary(path)
            replace_folder(path, self.files(render(index)))
            written()

    def files(self, arrays: SampleArrays) -> dict[str, bytes]:
        """A sequence folder's files by name, their bytes (:func:`entries`, encoded)."""
        return encode(entries(arrays))

    def sequences(self, out: Path) -> list[tuple[int, Path]]:
        """``(index, folder)`` of every sequence folder in ``out``, ascending."""
        names = [p.name for p in out.iterdir() if p.is_dir() and SEQUENCE_NAME.match(p.name)]
        return [(int(name), out / name) for name in sorted(names, key=int)]

    def read(self, out: Path, where: Path, name: str, limit: int) -> tuple[Path, bytes]:
        """``(where / name, its bytes)``, read as :func:`.files.read_inside` ``out``."""
        return where / name, read_inside(where / name, out, limit)

    def read_cameras(self, read: Callable[..., Any], config: dict[str, Any]) -> dict[str, np.ndarray]:
        """The checked cameras of ``cameras.json`` (:func:`.entries.cameras_entry`)."""
        return cameras_entry(read, config)

    def read_homographies(self, read: Callable[..., Any], n_views: int) -> np.ndarray:
        """``(V, V, 3, 3)`` float64 from the ``H_<i>_<j>.mat`` entries, each checked
        (:func:`.entries.checked_homography`), the identity on the diagonal."""
        homographies = np.zeros((n_views, n_views, 3, 3))
        homographies[np.arange(n_views), np.arange(n_views)] = np.eye(3)
        for i, j in itertools.permutations(range(n_views), 2):
            homographies[i, j] = read(homography_entry(i, j), (3, 3), checked_homography)
        return homographies
