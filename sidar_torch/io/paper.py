"""The SIDAR paper's own layout (``--layout paper``): the files its Blender generator writes, so that
tools made for the paper's data read ours, and :class:`~sidar_torch.ExportedDataset` reads the
paper's folders.

::

    000007/              the sequence of dataset index 7 (at least 6 digits)
      0.png .. <V-1>.png   the views, 8-bit RGB; view 0 is the reference camera
      0-m.png ..           the masks, 8-bit grey: 255 where the painting is not visible, else 0
                           (the paper's convention: white on occluders and off the painting)
      gt.png               the label
      H_<i>_<j>.mat        for i < j only, as the paper: ``np.savetxt`` text (three lines of three
                           ``%.18e`` numbers), view-i pixels to view-j pixels in the paper's pixel
                           convention, det = 1 (see :func:`paper_from_kornia`)
      homographies.npy     ours, exact: (V, V, 3, 3) float64 in Kornia pixels (the reader's source)
      cameras.json         ours: index, image size, K, R, t, homography error
      0-o.png .. 0-n.npy   the optional outputs switched on, as the folder layout (``choices.outputs.OUTPUTS``)

The paper's pixel convention puts the image's outer edges at ``0`` and ``W - 1`` (``x = (W - 1)
(ndc_x + 1) / 2``); Kornia's puts them at ``-0.5`` and ``W - 0.5`` (pixel centres at integers).

The paper's own folders (no ``export.json``) are read too (:func:`paper_manifest`): every
sub-folder holding ``gt.png`` is a sequence, in name order, indices ``0 .. N-1``. What is inferred
there: the image size (from ``gt.png``), the number of views (``0.png``, ``1.png``, ... up to the
first one missing), the homographies (``H_i_j.mat`` converted to Kornia pixels, det = 1;
``H[j, i]`` its inverse); RGBA pixels lose their alpha and the masks' antialiased grey edges become
255 from 128 up. Unknown there: the cameras (``K``, ``R``, ``t`` NaN), ``homography_error`` (NaN)
and the seed (``None``). The texts hold 17 digits: ``ExportedDataset(folder, geometry_dtype="float64")``
keeps them (float32 by default, as an export without a recorded ``geometry_dtype``).
"""

from __future__ import annotations

import io
import itertools
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, ClassVar

import numpy as np
from PIL import Image

from ..sample import SampleArrays
from .codecs import encode, png_size, unreadable
from .entries import (CAMERA_KEYS, HOMOGRAPHIES, camera_shape, checked_homographies, checked_homography,
                      sample_entries, unit_scaled)
from .files import open_inside
from .folders import FolderLayout, homography_entry
from .layout import MANIFEST

LABEL = "gt.png"


def paper_pixels(image_size: tuple[int, int]) -> np.ndarray:
    """``S`` ``(3, 3)`` float64 taking Kornia pixels to the paper's: ``x_paper = (x + 1/2) (W - 1) / W``,
    likewise for rows with ``H``; ``image_size = (H, W)``."""
    h, w = image_size
    return np.array([[(w - 1) / w, 0, (w - 1) / (2 * w)], [0, (h - 1) / h, (h - 1) / (2 * h)], [0, 0, 1]])


def _det_one(H: np.ndarray) -> np.ndarray:
    """``H`` ``(..., 3, 3)`` scaled to det = 1 by the signed cube root of its determinant."""
    return H / np.cbrt(np.linalg.det(H))[..., None, None]


def paper_from_kornia(H: np.ndarray, image_size: tuple[int, int]) -> np.ndarray:
    """A homography ``(3, 3)`` float64 between Kornia pixels as the paper writes it: ``S H S^-1``, det = 1."""
    S = paper_pixels(image_size)
    return _det_one(S @ H @ np.linalg.inv(S))


def kornia_from_paper(H: np.ndarray, image_size: tuple[int, int]) -> np.ndarray:
    """The inverse of :func:`paper_from_kornia`: ``S^-1 H S``, det = 1, ``(3, 3)`` float64."""
    S = paper_pixels(image_size)
    return _det_one(np.linalg.inv(S) @ H @ S)


def homography_text(H: np.ndarray) -> bytes:
    """``H`` ``(3, 3)`` as ``np.savetxt`` writes it (the paper's ``H_i_j.mat``)."""
    buffer = io.BytesIO()
    np.savetxt(buffer, H)
    return buffer.getvalue()


def read_homography_text(data: bytes, where: Path) -> np.ndarray:
    """The ``(3, 3)`` float64 homography of an ``H_i_j.mat`` text, all 17 digits of its numbers, checked
    whatever its scale (:func:`.entries.checked_homography`) and scaled by a power of two to
    ``0.5 <= max|H| < 1`` (exactly: the same homography, so that ``1e308 * H`` reads as ``H``).

    Raises:
        ValueError: naming ``where`` and what is wrong.
    """
    try:
        H = np.loadtxt(io.BytesIO(data), dtype=np.float64, ndmin=2)
    except ValueError as error:
        raise ValueError(f"{str(where)!r}: expected 3 lines of 3 numbers (np.savetxt text), got: {error}") from None
    try:
        return unit_scaled(checked_homography(H))
    except ValueError as error:
        raise ValueError(f"{str(where)!r}: {error}") from None


@dataclass(frozen=True)
class PaperLayout(FolderLayout):
    """The paper's layout as a :class:`~.layout.Layout`: one write unit per sequence folder, as
    :class:`.folders.FolderLayout`, with the paper's files (see the module's docstring)."""

    name: ClassVar[str] = "paper"

    def files(self, arrays: SampleArrays) -> dict[str, bytes]:
        """A sequence's files by name: the shared entries, ``homographies.npy``, and the paper's
        ``H_<i>_<j>.mat`` texts (``i < j``)."""
        files = encode({**sample_entries(arrays), HOMOGRAPHIES: arrays.homographies})
        size = arrays.label.shape[:2]
        for i, j in itertools.combinations(range(len(arrays.images)), 2):
            files[homography_entry(i, j)] = homography_text(paper_from_kornia(arrays.homographies[i, j], size))
        return files

    def sequences(self, out: Path) -> list[tuple[int, Path]]:
        """``(index, folder)`` of every sequence: our 6-digit folders, or (none there) every
        sub-folder holding ``gt.png`` in name order, numbered from 0 (the paper's folders).

        Raises:
            ValueError: one of the paper's folders holds another number of views than the first
                (the number the manifest records), naming both.
        """
        ours = super().sequences(out)
        if ours or (out / MANIFEST).exists():
            return ours
        folders = paper_folders(out)
        views = [view_count(folder) for folder in folders]
        for folder, count in zip(folders, views):
            if count != views[0]:
                raise ValueError(f"{str(folder)!r}: holds {count} views (0.png, 1.png, ...), {str(folders[0])!r} "
                                 f"{views[0]}: a folder of the paper's sequences holds sequences of one number of views")
        return list(enumerate(folders))

    def read(self, out: Path, where: Path, name: str, limit: int) -> tuple[Path, bytes]:
        """``(file, bytes)`` of entry ``name`` in the shared entries' encoding: our files as they
        are; the paper's converted (RGBA views and label to RGB, masks to 0 / 255 grey; see the
        module's docstring); ``H_i_j.mat`` texts as the shared codec's MATLAB file of the same
        homography (the paper's pixels; :func:`read_homography_text`).

        Raises:
            FileNotFoundError: no such entry; ValueError: as :meth:`FolderLayout.read`, and a PNG
            Pillow cannot read or of too many pixels (:func:`_ours`), naming the file.
        """
        path, data = super().read(out, where, name, limit)
        if name.endswith(".png"):
            return path, _ours(path, name, data, limit)
        if name.endswith(".mat"):  # the paper's text, handed on as the shared codec's MATLAB file (same numbers)
            return path, encode({name: read_homography_text(data, path)})[name]
        return path, data

    def read_cameras(self, read: Callable[..., Any], config: dict[str, Any]) -> dict[str, np.ndarray]:
        """The checked cameras of ``cameras.json`` where there is one (ours), else (the paper's
        sequences record none) NaN for every number of :data:`.entries.CAMERA_KEYS` (the cameras of
        each view, ``homography_error``; no ``lens``: pinhole cameras)."""
        try:
            return super().read_cameras(read, config)
        except FileNotFoundError:
            return {key.name: np.full(camera_shape(key, config["n_views"]), np.nan)
                    for key in CAMERA_KEYS if key.switch is None}

    def read_homographies(self, read: Callable[..., Any], n_views: int) -> np.ndarray:
        """``(V, V, 3, 3)`` float64: ``homographies.npy`` where there is one (ours; each checked,
        :func:`.entries.checked_homographies`), else the paper's ``H_i_j.mat`` texts
        (:func:`read_homography_text`) converted to Kornia pixels, det = 1, ``H[j, i]`` the inverse."""
        try:
            return read(HOMOGRAPHIES, (n_views, n_views, 3, 3), checked_homographies)
        except FileNotFoundError:
            pass
        size = read(LABEL).shape[:2]
        homographies = np.zeros((n_views, n_views, 3, 3))
        homographies[np.arange(n_views), np.arange(n_views)] = np.eye(3)
        for i, j in itertools.combinations(range(n_views), 2):
            H = kornia_from_paper(read(homography_entry(i, j)), size)
            homographies[i, j], homographies[j, i] = H, _det_one(np.linalg.inv(H))
        return homographies


PNG_BYTES_PER_PIXEL = 4
"""The most bytes Pillow holds a decoded PNG pixel in (RGB, RGBA, grey with alpha, 32-bit grey)."""


def _ours(path: Path, name: str, data: bytes, limit: int) -> bytes:
    """A PNG in our form: the bytes as they are when grey or RGB (ours), else (the paper's RGBA)
    converted: a mask ``<v>-m.png`` to grey 0 / 255 (255 from 128 up, its antialiased edges), any
    other to RGB (the alpha dropped). Its header's size is checked first: Pillow holds at most
    ``limit`` bytes of pixels (:data:`PNG_BYTES_PER_PIXEL`), the conversion about three times that.

    Raises:
        ValueError: naming ``path``: not a PNG Pillow reads, or one of more pixels than ``limit``
            bytes hold (the entry's :func:`.limits.entry_size_limit`).
    """
    size = png_size(data)
    if size is not None and PNG_BYTES_PER_PIXEL * size[0] * size[1] > limit:
        raise ValueError(f"{str(path)!r}: its header says {size[0]} x {size[1]} pixels (H x W), more than the "
                         f"{limit} bytes this export's files may hold at {PNG_BYTES_PER_PIXEL} bytes a pixel")
    try:
        with unreadable("PNG"), Image.open(io.BytesIO(data), formats=["PNG"]) as image:
            if image.mode in ("L", "RGB"):
                return data
            pixels = np.asarray(image.convert("RGB"))
    except ValueError as error:
        raise ValueError(f"{str(path)!r}: {error}") from None
    if name.endswith("-m.png"):
        pixels = np.where(pixels[..., 0] >= 128, 255, 0).astype(np.uint8)
    return encode({name: pixels})[name]


def view_count(folder: Path) -> int:
    """How many views a sequence folder holds: ``0.png``, ``1.png``, ... up to the first one missing."""
    count = 0
    while (folder / f"{count}.png").is_file():
        count += 1
    return count


def paper_folders(folder: Path) -> list[Path]:
    """The sub-folders of ``folder`` that hold ``gt.png`` and ``0.png`` (the paper's sequences), in name order."""
    return sorted((p for p in folder.iterdir() if p.is_dir() and (p / LABEL).is_file() and (p / "0.png").is_file()),
                  key=lambda p: p.name)


def paper_manifest(folder: Path) -> dict[str, Any]:
    """The manifest inferred for a folder of the paper's sequences (it has no ``export.json``):
    layout ``paper``, seed ``None``, config ``image_size`` from the first ``gt.png`` and
    ``n_views`` from its views ``0.png, 1.png, ...``.

    Raises:
        ValueError: ``folder`` holds no ``export.json`` and no sequence folder of the paper's
            layout, or the first one's ``gt.png`` is not a PNG, not a regular file (a FIFO is
            refused before it is opened, :func:`.files.open_inside`) or leads outside ``folder``
            (the message names it).
    """
    sequences = paper_folders(folder)
    if not sequences:
        raise ValueError(f"{str(folder)!r}: not a sidar_torch export (no {MANIFEST}) nor a folder of the SIDAR "
                         f"paper's sequences (sub-folders with {LABEL}, 0.png, 0-m.png, H_0_1.mat, ...)")
    first = sequences[0]
    with open_inside(first / LABEL, folder) as f:
        size = png_size(f.read(24))
    if size is None:
        raise ValueError(f"{str(first / LABEL)!r}: not a PNG")
    return {"layout": PaperLayout.name, "shard_size": None, "seed": None,
            "source": {"kind": "the SIDAR paper's sequences", "folder": str(folder)},
            "config": {"image_size": list(size), "n_views": view_count(first)}}
