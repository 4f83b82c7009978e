"""What the export layouts share: the interface each answers (:class:`Layout`, its write unit
:class:`WriteUnit`), names and codecs (the files are :mod:`.files`, the manifest :mod:`.manifest`,
the table of layouts :mod:`.layouts`).

A sequence is written as named entries (``0.png``, ``gt.png``, ``cameras.json``, ...): the
writers (:mod:`.folders`, :mod:`.shards`) name them, :data:`ENCODERS` turns each into bytes by its
extension and :data:`DECODERS` reads it back. The pixel entries come from the sample table
(:data:`sidar_torch.sample.KEYS`, column ``entry``), so a new 8-bit output is exported and read
back without a change here.
"""

from __future__ import annotations

import io
import json
import os
import re
import struct
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, ClassVar, Protocol, runtime_checkable

import numpy as np
import scipy.io
from PIL import Image

from ..sample import KEYS, SampleArrays, present_keys

MANIFEST = "export.json"
CONFIG = "config.yaml"
SEQUENCE_NAME = re.compile(r"^\d{6,}$")
SHARD_NAME = re.compile(r"^shard-(\d{5,})\.tar$")
CAMERAS = "cameras.json"
MAT_HEADER = b"MATLAB 5.0 MAT-file, written by sidar_torch"
"""Replaces scipy's header text, which holds the time of writing, so equal data gives equal files."""


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

    def read_homographies(self, read: Callable[[str], Any], n_views: int) -> np.ndarray:
        """``(V, V, 3, 3)`` float64 homographies of a sequence from its decoded entries (``read``:
        entry name -> value), the identity on the diagonal."""


def sequence_name(index: int) -> str:
    """The name of sequence ``index``: its 6-digit (or longer) index."""
    return f"{index:06d}"


def is_export_name(name: str) -> bool:
    """True for a name an export writes at its top: a sequence folder, a shard, the manifest or the config."""
    return bool(SEQUENCE_NAME.match(name) or SHARD_NAME.match(name)) or name in (MANIFEST, CONFIG)


# --------------------------------------------------------------------------- codecs


def _png(pixels: np.ndarray) -> bytes:
    buffer = io.BytesIO()
    Image.fromarray(pixels).save(buffer, format="PNG")
    return buffer.getvalue()


def _mat(H: np.ndarray) -> bytes:
    """A MATLAB 5 file with variable ``H`` (3 x 3 float64), with a fixed header text."""
    buffer = io.BytesIO()
    scipy.io.savemat(buffer, {"H": np.ascontiguousarray(H, dtype=np.float64)})
    data = buffer.getvalue()
    return MAT_HEADER.ljust(116) + data[116:]  # the format's first 116 bytes are free text


def _npy(array: np.ndarray) -> bytes:
    buffer = io.BytesIO()
    np.save(buffer, array)
    return buffer.getvalue()


def _json(data: dict[str, Any]) -> bytes:
    return (json.dumps(data, indent=1) + "\n").encode()


PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def png_size(data: bytes) -> tuple[int, int] | None:
    """``(H, W)`` pixels from the header of the PNG ``data`` (nothing decoded), or None if it is not a PNG."""
    if len(data) < 24 or not data.startswith(PNG_SIGNATURE) or data[12:16] != b"IHDR":
        return None
    width, height = struct.unpack(">II", data[16:24])
    return height, width


def _read_png(data: bytes) -> np.ndarray:
    with Image.open(io.BytesIO(data)) as image:
        return np.array(image)


ENCODERS: dict[str, Callable[[Any], bytes]] = {".png": _png, ".mat": _mat, ".npy": _npy, ".json": _json}
"""Entry extension -> encoder: ``.png`` uint8 ``(H, W)`` or ``(H, W, 3)``, ``.mat`` a 3 x 3 float64
``H``, ``.npy`` any array, ``.json`` a dict."""

DECODERS: dict[str, Callable[[bytes], Any]] = {
    ".png": _read_png, ".mat": lambda data: scipy.io.loadmat(io.BytesIO(data))["H"],
    ".npy": lambda data: np.load(io.BytesIO(data)), ".json": json.loads,
}
"""Entry extension -> decoder, the inverse of :data:`ENCODERS`."""


def encode(entries: dict[str, Any]) -> dict[str, bytes]:
    """``{name: value}`` -> ``{name: bytes}``, each by its name's extension."""
    return {name: ENCODERS[os.path.splitext(name)[1]](value) for name, value in entries.items()}


def decode(name: str, data: bytes) -> Any:
    return DECODERS[os.path.splitext(name)[1]](data)


# --------------------------------------------------------------------------- sequences as entries


def sample_entries(arrays: SampleArrays) -> dict[str, Any]:
    """The entries both layouts share, in writing order: per view the 8-bit pixel keys of the
    sample table (``0.png``, ``0-m.png``, ``0-o.png`` if rendered, ...), then the whole-image ones
    (``gt.png``), then ``cameras.json`` (index, image size, K, R, t, homography error)."""
    n_views = len(arrays.images)
    pixel_keys = [key for key in KEYS if key.entry is not None and getattr(arrays, key.name) is not None]
    entries = {key.entry.format(v=v): getattr(arrays, key.name)[v]
               for v in range(n_views) for key in pixel_keys if "{v}" in key.entry}
    entries.update({key.entry: getattr(arrays, key.name) for key in pixel_keys if "{v}" not in key.entry})
    entries[CAMERAS] = {
        "index": arrays.index,
        "image_size": list(arrays.label.shape[:2]),
        "K": arrays.K.tolist(),
        "R": arrays.R.tolist(),
        "t": arrays.t.tolist(),
        "homography_error": arrays.homography_error,
        "frame": "OpenCV camera frame (x right, y down, z forward): world point X lands at K (R X + t); "
                 "K in pixels, Kornia pixel centres",
    }
    return entries


def pixel_entries_text() -> str:
    """The 8-bit pixel files of a sequence, for help texts: ``"<i>.png (images), <i>-m.png (masks), ..."``."""
    return ", ".join(f"{key.entry.format(v='<i>')} ({key.name}{', with ' + key.switch if key.switch else ''})"
                     for key in KEYS if key.entry is not None)


def sample_from_entries(read: Callable[[str], Any], index: int, config: dict[str, Any],
                        homographies: Callable[[int], np.ndarray]) -> SampleArrays:
    """Rebuild the :class:`SampleArrays` of sequence ``index`` from its decoded entries.

    Args:
        read: entry name -> decoded value (raises ``FileNotFoundError`` naming a missing entry).
        index: the sequence's dataset index.
        config: the recorded config (says which keys are present, e.g. ``opacities``).
        homographies: ``V`` -> the ``(V, V, 3, 3)`` float64 homographies, read the layout's way.
    """
    cameras = read(CAMERAS)
    n_views = len(cameras["K"])
    pixels = {}
    for key in present_keys(config):
        if key.entry is None:
            continue
        if "{v}" not in key.entry:
            pixels[key.name] = read(key.entry)
            continue
        views = [read(key.entry.format(v=v)) for v in range(n_views)]
        shapes = sorted({view.shape for view in views})
        if len(shapes) > 1:
            raise ValueError(f"SampleArrays.{key.name}: the files {key.entry.format(v='<v>')} of sequence {index} "
                             f"differ in shape: {shapes}")
        pixels[key.name] = np.stack(views)
    return SampleArrays(**pixels, homographies=homographies(n_views),
                        homography_error=float(cameras["homography_error"]),
                        K=np.array(cameras["K"], dtype=np.float64), R=np.array(cameras["R"], dtype=np.float64),
                        t=np.array(cameras["t"], dtype=np.float64), index=index)
