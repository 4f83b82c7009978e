"""Painting sources: where the paintings come from (``docs/paintings.md`` says what each accepts).

A :class:`PaintingSource` gives painting number ``i`` at an exact size as ``(H, W, 3)`` uint8 RGB;
:func:`make_source` turns whatever the user passes as ``source`` into one: ``None`` the built-in
:class:`ProceduralPaintings`; a folder, a file or a list of files :class:`ImageFiles`; a tensor or a
NumPy array :class:`TensorPaintings`; a list of tensors, NumPy arrays or PIL images :class:`ImageList`;
any indexable dataset of images :class:`DatasetPaintings`. Every source accepts any index ``>= 0`` (``index % len(source)``)
and keeps only plain data, so it pickles into ``DataLoader`` workers. Bad images: ``on_bad_image``
(``"raise"`` or ``"skip"``) and :meth:`ImageFiles.scan`.
"""

from __future__ import annotations

import abc
import hashlib
import operator
import os
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import torch
from PIL import Image

from ..config import ON_BAD_IMAGE
from . import procedural
from .decode import (CROP_MODES, MAX_IMAGE_PIXELS, PaintingSize, array_to_uint8, check_choice, check_size,
                     chw_to_image, fit_painting, load_image, tensor_to_uint8, to_rgb)

__all__ = ["IMAGE_EXTENSIONS", "BadImageWarning", "DatasetPaintings", "ImageFiles", "ImageList", "PaintingSource",
           "ProceduralPaintings", "TensorPaintings", "make_source"]

IMAGE_EXTENSIONS = frozenset({".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp", ".gif"})
"""File extensions (lower case) picked up when a folder is scanned."""

class BadImageWarning(UserWarning):
    """An image could not be read and was skipped (``on_bad_image="skip"``)."""


_WARNED: set[str] = set()
"""Names of the unreadable images this process has warned about: one warning per image and process,
whichever source (or copy of a source) met it. Forked workers inherit it."""


def _check_index(index: Any, length: int) -> int:
    """Return ``index % length`` after checking ``index`` is an int ``>= 0``."""
    value = operator.index(index)
    if value < 0:
        raise ValueError(f"painting index must be >= 0, got {value}")
    return value % length


def _list_images(folder: Path) -> list[str]:
    """Every image file below ``folder`` (recursive, following symbolic links to folders), sorted by
    relative POSIX path.

    Each real folder is walked once, whatever number of links reach it: a folder already walked
    (the same ``(st_dev, st_ino)``) is not entered again, so a loop ends and a tree with several
    links per level stays linear. Sub-folders are walked in sorted order, so which of several paths
    names a linked folder is the same on every machine: the first in that order. Unreadable folders
    raise the OS error (e.g. ``PermissionError``), which names the folder.
    """

    def fail(error: OSError) -> None:
        raise error

    def identity(path: str) -> tuple[int, int]:
        status = os.stat(path)
        return status.st_dev, status.st_ino

    walked = {identity(folder)}
    found: list[tuple[str, str]] = []
    for dirpath, dirnames, filenames in os.walk(folder, onerror=fail, followlinks=True):
        fresh = []
        for name in sorted(dirnames):
            key = identity(os.path.join(dirpath, name))
            if key not in walked:
                walked.add(key)
                fresh.append(name)
        dirnames[:] = fresh
        for name in filenames:
            if os.path.splitext(name)[1].lower() in IMAGE_EXTENSIONS:
                full = os.path.join(dirpath, name)
                found.append((Path(os.path.relpath(full, folder)).as_posix(), full))
    return [full for _, full in sorted(found)]


def _check_files(paths: Sequence[str | os.PathLike[str]]) -> None:
    """Raise ``FileNotFoundError`` / ``IsADirectoryError`` for paths that are not existing files."""
    for path in paths:
        if not os.path.exists(path):
            raise FileNotFoundError(f"painting file not found: {os.fspath(path)!r}")
        if os.path.isdir(path):
            raise IsADirectoryError(f"expected an image file, got a folder: {os.fspath(path)!r}")


# --------------------------------------------------------------------------- sources


class PaintingSource(abc.ABC):
    """A finite, indexable collection of paintings, each rendered at any size."""

    @abc.abstractmethod
    def __len__(self) -> int:
        """Number of distinct paintings (``>= 1``)."""

    @abc.abstractmethod
    def painting(self, index: int, size: PaintingSize) -> np.ndarray:
        """Painting ``index % len(self)`` at ``size = (H, W)`` pixels.

        Returns:
            ``(H, W, 3)`` ``uint8`` C-contiguous RGB array.

        Raises:
            ValueError: ``index < 0`` or ``size`` is not two positive ints.
        """

    def describe(self) -> dict[str, Any]:
        """Plain data (JSON-ready) that tells this source from another, as an export records it:
        ``{"type": class name, "paintings": len(self)}``; sources add what sets their paintings apart."""
        return {"type": type(self).__name__, "paintings": len(self)}


class _ImageSource(PaintingSource):
    """A source backed by images of their own size, fitted with :func:`fit_painting`."""

    def __init__(self, crop: str) -> None:
        self.crop = check_choice("crop", crop, CROP_MODES)

    @abc.abstractmethod
    def _image(self, index: int, size: PaintingSize) -> Image.Image:
        """RGB image number ``index`` (``0 <= index < len(self)``) before fitting to ``size``."""

    def painting(self, index: int, size: PaintingSize) -> np.ndarray:
        size = check_size(size)
        return fit_painting(self._image(_check_index(index, len(self)), size), size, self.crop)

    def describe(self) -> dict[str, Any]:
        """:meth:`PaintingSource.describe` and ``"crop"``."""
        return {**super().describe(), "crop": self.crop}


class _ReadingSource(_ImageSource):
    """An image source that reads each image only when its painting is requested, so reading can fail.

    What happens to an image that cannot be read is ``on_bad_image``'s choice (see "Bad input" in
    the module docstring).

    Attributes:
        bad_images: ``{name: "<error type>: <message>"}`` of the images *this process* found
            unreadable so far (a DataLoader worker's never reach the main process: :meth:`scan`
            finds them all up front).
        kept: the positions, in the source's own list (files, dataset items), of the images that
            indices ``0 .. len(self) - 1`` show: all of them, until :meth:`scan` with
            ``on_bad_image="skip"`` drops the unreadable ones.
    """

    def __init__(self, crop: str, on_bad_image: str, count: int) -> None:
        super().__init__(crop)
        self.on_bad_image = check_choice("on_bad_image", on_bad_image, ON_BAD_IMAGE)
        self.bad_images: dict[str, str] = {}
        self.kept: Sequence[int] = range(count)

    def __len__(self) -> int:
        return len(self.kept)

    def scan(self, size: PaintingSize = (64, 64)) -> dict[str, str]:
        """Read every image once (at ``size``, a cheap draft for large JPEGs) and record the unreadable ones.

        With ``on_bad_image="skip"`` they are then dropped: ``len(self)`` counts the readable images
        and each index shows its own painting (no two indices show one image, as the fallback to the
        next readable image does for an image found bad later). Indices map to other images after
        the scan than before it: call it once, in the main process, before iterating or exporting.
        The DataLoader workers then get the source with the bad images already dropped, so they
        neither read nor warn about them. With ``on_bad_image="raise"`` the images are only
        reported (requesting one still raises).

        Returns:
            ``bad_images``: ``{name: "<error type>: <message>"}`` of every image that cannot be read.

        Raises:
            ValueError: ``on_bad_image="skip"`` and no image can be read.
        """
        size = check_size(size)
        for position in self.kept:
            name = self._name(position)
            if name not in self.bad_images:
                try:
                    self._read(position, size)
                except Exception as exc:  # as in _image
                    self._record_bad(name, exc)
        if self.on_bad_image == "skip":
            readable = [position for position in self.kept if self._name(position) not in self.bad_images]
            if not readable:
                raise self._none_readable(self._name(self.kept[0]))
            self.kept = readable
        return dict(self.bad_images)

    def _record_bad(self, name: str, exc: Exception) -> None:
        """Remember that image ``name`` cannot be read; warn unless this process warned about it before.

        The warning's location is the image itself (``<name>:0``), not a line of this package: it is
        the file to look at, wherever (which worker, which call) it was met."""
        self.bad_images[name] = f"{type(exc).__name__}: {exc}"
        if name not in _WARNED:
            _WARNED.add(name)
            warnings.warn_explicit(
                f"on_bad_image='skip': skipping unreadable image {name}: {self.bad_images[name]} (each process "
                "warns once per image; source.scan() in the main process finds every unreadable image up front "
                "and drops them)", BadImageWarning, filename=name, lineno=0)

    def _none_readable(self, name: str) -> ValueError:
        return ValueError(
            f"on_bad_image='skip', but none of the {len(self.kept)} images of this {type(self).__name__} can be "
            f"read; {name}: {self.bad_images[name]}")

    @abc.abstractmethod
    def _read(self, position: int, size: PaintingSize) -> Image.Image:
        """Read the image at ``position`` of the source's own list as in :meth:`_image`, raising whatever
        reading raises."""

    @abc.abstractmethod
    def _name(self, position: int) -> str:
        """How warnings and errors name the image at ``position`` of the source's own list."""

    def _image(self, index: int, size: PaintingSize) -> Image.Image:
        if self.on_bad_image == "raise":
            return self._read(self.kept[index], size)
        for offset in range(len(self)):
            position = self.kept[(index + offset) % len(self)]
            name = self._name(position)
            if name in self.bad_images:
                continue
            try:
                return self._read(position, size)
            except Exception as exc:  # Pillow and users' datasets raise many types for bad data
                self._record_bad(name, exc)
        raise self._none_readable(self._name(self.kept[index]))


class ImageFiles(_ReadingSource):
    """Paintings read lazily from image files, in the given order.

    Args:
        paths: image files; they are opened only in :meth:`painting` (or :meth:`scan`).
        crop: see :func:`fit_painting`.
        on_bad_image: ``"raise"`` or ``"skip"``, for a file that cannot be
            read (see "Bad input" in the module docstring).
        max_pixels: the pixel budget of a file (width x height, read from its
            header before decoding; the config field ``max_image_pixels``): a
            larger file is a bad image.

    With ``"raise"``, a file that cannot be decoded raises ``ValueError``
    naming it and the cause (:class:`ImageTooLargeError`, a ``ValueError``,
    for one above ``max_pixels``, with its size); a missing or unreadable one
    raises the OS error (``FileNotFoundError``, ``PermissionError``), which
    names it too.
    """

    def __init__(self, paths: Sequence[str | os.PathLike[str]], *, crop: str = "center", on_bad_image: str = "raise",
                 max_pixels: int = MAX_IMAGE_PIXELS) -> None:
        super().__init__(crop, on_bad_image, len(paths))
        self.paths = tuple(os.path.abspath(path) for path in paths)
        if not self.paths:
            raise ValueError("ImageFiles needs at least one path, got an empty list")
        self.max_pixels = operator.index(max_pixels)
        if self.max_pixels < 1:
            raise ValueError(f"max_pixels must be at least 1, got {self.max_pixels}")

    def describe(self) -> dict[str, Any]:
        """:meth:`PaintingSource.describe`, ``"crop"``, the ``"first_path"`` and ``"paths_sha256"``,
        the SHA-256 of the paths' bytes joined by newlines (so that any name the system allows is described)."""
        paths_sha256 = hashlib.sha256(b"\n".join(map(os.fsencode, self.paths))).hexdigest()
        return {**super().describe(), "first_path": self.paths[0], "paths_sha256": paths_sha256}

    def _name(self, position: int) -> str:
        return self.paths[position]

    def _read(self, position: int, size: PaintingSize) -> Image.Image:
        return load_image(self.paths[position], size, self.max_pixels)


class TensorPaintings(_ImageSource):
    """Paintings from one image tensor or NumPy array.

    Args:
        images: a tensor ``(N, 3, h, w)`` or ``(3, h, w)``, or a NumPy array ``(N, h, w, 3)``,
            ``(h, w, 3)`` or ``(h, w)`` (channels last, :func:`~.decode.array_to_uint8`); float in
            ``[0, 1]`` or ``uint8``. Stored as a CPU ``uint8`` copy (``round(x * 255)``).
        crop: see :func:`fit_painting`.
    """

    def __init__(self, images: torch.Tensor | np.ndarray, *, crop: str = "center") -> None:
        super().__init__(crop)
        self.images = (array_to_uint8(images, batched=True, name="source array") if isinstance(images, np.ndarray)
                       else tensor_to_uint8(images, batched=True))

    def __len__(self) -> int:
        return self.images.shape[0]

    def _image(self, index: int, size: PaintingSize) -> Image.Image:
        return chw_to_image(self.images[index])


class ImageList(_ImageSource):
    """Paintings from a list of ``(3, h, w)`` tensors, NumPy images (``(h, w, 3)``, ``(h, w)``,
    channels last) and/or PIL images (sizes may differ).

    Every item is converted to ``uint8`` RGB when the source is built (PIL
    images with :func:`~.decode.to_rgb`, tensors and arrays as in :class:`TensorPaintings`) and
    kept as an ``(h, w, 3)`` array.
    """

    def __init__(self, images: Sequence[torch.Tensor | np.ndarray | Image.Image], *, crop: str = "center") -> None:
        super().__init__(crop)
        if len(images) == 0:
            raise ValueError("ImageList needs at least one image, got an empty list")
        self.images = [np.asarray(_item_to_image(item, position)) for position, item in enumerate(images)]

    def __len__(self) -> int:
        return len(self.images)

    def _image(self, index: int, size: PaintingSize) -> Image.Image:
        return Image.fromarray(self.images[index], "RGB")


class DatasetPaintings(_ReadingSource):
    """Paintings from an indexable dataset, read lazily.

    Args:
        dataset: object with ``__len__`` and ``__getitem__``; item ``i`` is a
            ``(3, h, w)`` tensor, a NumPy image (``(h, w, 3)``, ``(h, w)``), a PIL
            image, or a tuple/list whose first element is one (e.g. ``(image, label)``).
        crop: see :func:`fit_painting`.
        on_bad_image: ``"raise"`` or ``"skip"``, for an item whose loading
            raises or that is not a valid image (see "Bad input" in the
            module docstring).

    The dataset itself must be picklable for use with ``DataLoader`` workers.
    """

    def __init__(self, dataset: Any, *, crop: str = "center", on_bad_image: str = "raise") -> None:
        super().__init__(crop, on_bad_image, len(dataset))
        if len(dataset) == 0:
            raise ValueError("source dataset is empty")
        self.dataset = dataset

    def _name(self, position: int) -> str:
        return f"dataset item {position}"

    def _read(self, position: int, size: PaintingSize) -> Image.Image:
        item = self.dataset[position]
        if isinstance(item, (tuple, list)) and item:
            item = item[0]
        return _item_to_image(item, position)


def _item_to_image(item: Any, position: int) -> Image.Image:
    """A ``(3, h, w)`` tensor, a NumPy image (channels last) or a PIL image -> PIL RGB image; else ``TypeError``."""
    if isinstance(item, torch.Tensor):
        return chw_to_image(tensor_to_uint8(item, batched=False, name=f"painting item {position}"))
    if isinstance(item, np.ndarray):
        return chw_to_image(array_to_uint8(item, batched=False, name=f"painting item {position}"))
    if isinstance(item, Image.Image):
        return to_rgb(item)
    raise TypeError(f"painting item {position} must be a (3, h, w) torch.Tensor, a NumPy image (h, w, 3) or (h, w), "
                    f"or a PIL image, got {type(item).__name__}")


# --------------------------------------------------------------------------- procedural paintings


class ProceduralPaintings(PaintingSource):
    """Deterministic synthetic paintings (:func:`sidar_torch.procedural.paint`): the built-in default source.

    ``painting(i, size)`` is a pure function of ``(i % count, size)``: it uses
    its own ``numpy.random.default_rng([0x5EED, i % count])``. One index at two
    sizes shows the same painting (all geometry is relative to the size).

    Args:
        count: number of distinct paintings (``len``), ``>= 1``.
    """

    SEED = 0x5EED

    def __init__(self, count: int = 100_000) -> None:
        count = operator.index(count)
        if count < 1:
            raise ValueError(f"count must be >= 1, got {count}")
        self.count = count

    def __len__(self) -> int:
        return self.count

    def painting(self, index: int, size: PaintingSize) -> np.ndarray:
        height, width = check_size(size)
        return procedural.paint(np.random.default_rng([self.SEED, _check_index(index, self.count)]), height, width)


# --------------------------------------------------------------------------- make_source


_ACCEPTED = (
    "None (procedural paintings), a folder or image file path (str or os.PathLike), a list/tuple of image "
    "paths, a torch.Tensor of shape (N, 3, h, w) or (3, h, w), a NumPy array of shape (N, h, w, 3), (h, w, 3) "
    "or (h, w) (channels last), a list/tuple of (3, h, w) tensors, NumPy images and/or PIL images, a "
    "PaintingSource, or a dataset with __len__ and __getitem__ whose items are a tensor, a NumPy image, a PIL "
    "image, or a tuple starting with one"
)


def _source_from_path(path: str | os.PathLike[str], crop: str, on_bad_image: str, max_pixels: int) -> ImageFiles:
    if not os.path.isdir(path):
        _check_files([path])
        return ImageFiles([path], crop=crop, on_bad_image=on_bad_image, max_pixels=max_pixels)
    files = _list_images(Path(path))
    if not files:
        raise ValueError(
            f"no image files ({', '.join(sorted(IMAGE_EXTENSIONS))}) found in folder {os.fspath(path)!r} or below"
        )
    return ImageFiles(files, crop=crop, on_bad_image=on_bad_image, max_pixels=max_pixels)


def _source_from_sequence(items: Sequence[Any], crop: str, on_bad_image: str, max_pixels: int) -> PaintingSource:
    if len(items) == 0:
        raise ValueError("source is an empty list/tuple")
    if all(isinstance(item, (str, os.PathLike)) for item in items):
        _check_files(items)
        return ImageFiles(items, crop=crop, on_bad_image=on_bad_image, max_pixels=max_pixels)
    if all(isinstance(item, (torch.Tensor, np.ndarray, Image.Image)) for item in items):
        return ImageList(items, crop=crop)
    raise TypeError(
        "source list/tuple must hold only image paths or only tensors/NumPy arrays/PIL images; "
        f"got element types {sorted({type(item).__name__ for item in items})}. Accepted sources: {_ACCEPTED}"
    )


def _is_dataset(obj: Any) -> bool:
    return (
        hasattr(obj, "__len__")
        and hasattr(obj, "__getitem__")
        and not isinstance(obj, (str, bytes, bytearray, Mapping, np.ndarray))
    )


def make_source(source: Any, *, crop: str = "center", on_bad_image: str = "raise",
                max_pixels: int = MAX_IMAGE_PIXELS) -> PaintingSource:
    """Build the painting source for ``source`` (see the module docstring for the accepted kinds).

    Args:
        source: ``None``, a path, a list/tuple of paths, tensors, NumPy arrays or PIL
            images, a tensor, a NumPy array, a :class:`PaintingSource`, or an indexable dataset.
        crop: ``"center"`` or ``"none"``, used by image-backed sources built
            here (ignored for ``None`` and for an existing source).
        on_bad_image: ``"raise"`` or ``"skip"``: what sources that read
            lazily (files, folders, datasets) do with an image that cannot be
            read (see "Bad input" in the module docstring; ignored for the
            other kinds and for an existing source).
        max_pixels: the pixel budget of an image file (see "Large images" in
            the module docstring; the config field ``max_image_pixels``).

    Raises:
        TypeError: ``source`` is of no accepted kind.
        FileNotFoundError: a path does not exist.
        IsADirectoryError: a path list holds a folder.
        PermissionError: a folder or sub-folder cannot be listed.
        ValueError: empty folder/list/tensor/dataset, invalid tensor or array (the message names
            the call that fixes an evident layout or range mistake), invalid ``crop`` or ``on_bad_image``.
    """
    crop = check_choice("crop", crop, CROP_MODES)
    on_bad_image = check_choice("on_bad_image", on_bad_image, ON_BAD_IMAGE)
    if source is None:
        return ProceduralPaintings()
    if isinstance(source, PaintingSource):
        return source
    if isinstance(source, (str, os.PathLike)):
        return _source_from_path(source, crop, on_bad_image, max_pixels)
    if isinstance(source, (torch.Tensor, np.ndarray)):
        return TensorPaintings(source, crop=crop)
    if isinstance(source, (list, tuple)):
        return _source_from_sequence(source, crop, on_bad_image, max_pixels)
    if _is_dataset(source):
        return DatasetPaintings(source, crop=crop, on_bad_image=on_bad_image)
    raise TypeError(f"source must be one of: {_ACCEPTED}; got {type(source).__name__}")
