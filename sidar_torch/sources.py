"""Painting sources: the images used as textures.

A *painting source* gives painting number ``i`` at an exact output size as an
``(H, W, 3)`` ``uint8`` RGB array. :func:`make_source` turns whatever the user
passes as ``source`` into a :class:`PaintingSource`:

* ``None`` -> :class:`ProceduralPaintings`, a deterministic generator of
  synthetic paintings, so that the package runs with no data at all;
* a folder -> :class:`ImageFiles` over every image file below it (recursively,
  following symbolic links to folders, each real folder once however many links
  reach it, so loops end and the listing stays linear in the number of folders;
  extensions in :data:`IMAGE_EXTENSIONS`, case-insensitive), sorted
  by their relative POSIX path so that the order is the same on every machine;
  files are named by absolute paths, so one folder spelled two ways is one source;
* a single image file, or a list/tuple of image files -> :class:`ImageFiles`
  (given order);
* a ``torch.Tensor`` of shape ``(N, 3, h, w)`` or ``(3, h, w)`` ->
  :class:`TensorPaintings`;
* a list/tuple of ``(3, h, w)`` tensors and/or ``PIL.Image.Image`` (mixed,
  sizes may differ) -> :class:`ImageList`;
* an existing :class:`PaintingSource` -> returned unchanged;
* any other object with ``__len__`` and ``__getitem__`` (e.g. a
  torchvision-style dataset) whose items are a tensor, a PIL image, or a tuple
  whose first element is one -> :class:`DatasetPaintings`.

Every source accepts any index ``>= 0`` and uses ``index % len(source)``.

Tensors are float with values in ``[0, 1]`` (converted with
``round(x * 255)``) or ``uint8`` (``0..255``), channels in RGB order.

Crop and resample rule
----------------------
All image-backed sources map an image of ``w0 x h0`` pixels to the requested
``(H, W)`` in the same way (:func:`fit_painting`):

* ``crop="center"`` (default): the largest box with exactly the output aspect
  ``W / H`` centred in the image is cut out. The box is computed in floating
  point (so it may start or end at a fraction of a pixel) and resampled to
  ``W x H`` with Pillow's Lanczos filter, which is antialiased when
  downscaling. Output pixel ``(y, x)`` therefore shows the image at
  ``(y0 + (y + 0.5) * s - 0.5, x0 + (x + 0.5) * s - 0.5)`` in source pixel
  coordinates, with one scale ``s = min(w0 / W, h0 / H)`` for both axes,
  ``x0 = (w0 - W * s) / 2`` and ``y0 = (h0 - H * s) / 2``.
* ``crop="none"``: the whole image is stretched to ``W x H`` (the two axes
  may get different scales), also with Lanczos.
* An image that already is exactly ``W x H`` is returned pixel for pixel,
  without resampling, whatever ``crop`` is.

Colour modes
------------
Files and PIL images are first rotated/flipped according to their EXIF
orientation tag (``PIL.ImageOps.exif_transpose``), then converted to 8-bit
RGB:

* images with alpha (``RGBA``, ``LA``, ``PA``, ``RGBa``, palette or ``L``/
  ``RGB`` with a transparency key) are composited over **black**, i.e. each
  colour channel is multiplied by ``alpha / 255``;
* 16-bit integer images (modes ``I;16*``, and ``I`` which Pillow uses for
  16-bit PNG/TIFF) are scaled from ``0..65535`` to ``0..255`` with
  ``round(v * 255 / 65535)`` (values of ``I`` outside ``0..65535`` are
  clipped to it);
* float images (mode ``F``) whose finite values all lie in ``[0, 1]`` are
  scaled by 255; otherwise their values are taken as ``0..255`` and clipped.
  NaN becomes 0, infinities become 0 or 255;
* every other mode (``1``, ``L``, ``P``, ``CMYK``, ``YCbCr``, ``LAB``, ...)
  uses Pillow's own conversion to RGB.

16-bit RGB and RGBA PNGs never reach these rules as 16-bit data: Pillow
opens them as 8-bit ``RGB``/``RGBA``, keeping the high byte of each value
(``v >> 8``).

Large images
------------
Files are decoded only when a painting is requested, and only if the size
their header claims (``Image.open`` reads the header alone) is within a pixel
budget, ``max_pixels`` (the config field ``max_image_pixels``, default
:data:`MAX_IMAGE_PIXELS` = ``2**28`` = 268,435,456, e.g. 16384 x 16384: far
above any real painting), for every format. A file above it is a bad image
(see below: :class:`ImageTooLargeError` naming the file and its size, or
skipped), so a small file that claims a huge size (a "decompression bomb": a
1.2 KB PNG can claim 100000 x 100000) never takes the memory. Raise the budget
for larger paintings; decoding needs about 3 bytes per pixel, and more while
converting.

Pillow's own, process-wide limit ``PIL.Image.MAX_IMAGE_PIXELS`` (89,478,485 by
default) applies too, and this package never changes it: Pillow warns
(``DecompressionBombWarning``) above it and refuses images above twice it
(178,956,970 pixels by default), which is then a bad image whose message says
so. A program that paints with larger images sets
``PIL.Image.MAX_IMAGE_PIXELS = None`` (Pillow's switch) and lets
``max_image_pixels`` decide.

A JPEG with more than :data:`JPEG_DRAFT_PIXELS` (89,478,485) pixels is
decoded directly at 1/2, 1/4 or 1/8 scale (libjpeg DCT scaling via
``Image.draft``) but never below the output size, and the crop box is computed
on the reduced image (the reduction rounds image sizes up, which can shift the
crop by less than one reduced pixel). Other formats are decoded at full size.

Bad input
---------
Problems with the ``source`` argument itself are found when the source is
built and always raise, whatever ``on_bad_image`` says: a path that does not
exist (``FileNotFoundError``), a folder or sub-folder that cannot be listed
(``PermissionError``), a folder given in a path list (``IsADirectoryError``),
all naming the path; a folder with no image files below it, an empty list,
tensor or dataset (``ValueError``); a tensor of the wrong shape or dtype, with
NaN or infinite values, or float values outside ``[0, 1]`` (``ValueError``
naming the item and what was expected).

Files and dataset items are read only when their painting is requested (or by
``source.scan()``), so a bad one is found then: a truncated or corrupt file, a
file whose header claims more pixels than ``max_pixels``, a non-image file with
an image extension, a file without read permission or deleted since the folder
was listed, a dataset item whose loading raises or that is not an image. The
``on_bad_image`` argument (``SidarConfig.on_bad_image``) decides:

* ``"raise"`` (default): the error propagates. Files give ``ValueError``
  ("cannot decode image file '<path>': <Pillow's reason>"),
  :class:`ImageTooLargeError` (a ``ValueError`` with the path and the size) or
  the OS error (``PermissionError``, ``FileNotFoundError``), which names the
  file; dataset items give whatever the dataset raised, or ``TypeError`` /
  ``ValueError`` naming the item if it is not a valid image.
* ``"skip"``: an unreadable image gives one :class:`BadImageWarning` per
  process, located at the image (``<path>:0: BadImageWarning: ...``, so that
  the file is what the warning points at), and is recorded in the source's
  ``bad_images`` (``{name: reason}``; the name is the file's absolute path or
  ``"dataset item <i>"``) so that it is not read again. Which painting an index
  then shows depends on whether the source was scanned:

  - **after** ``source.scan()`` (recommended: call it once in the main process,
    before iterating or exporting): every image is read once up front and the
    unreadable ones are dropped, so ``len(source)`` counts readable images,
    every index shows its own painting, the main process knows every bad image
    (``scan()`` returns them) and DataLoader workers neither read nor warn
    about them again. The scan costs one decode per image (at reduced scale for
    large JPEGs), which is why it is not done when the source is built.
  - **without a scan**, or for an image that turns bad after it (deleted, say):
    painting ``i`` is the first readable image of ``i, i + 1, ...`` (wrapping
    around), so the bad image's index shows the same painting as the next
    index. This keeps a sample a pure function of its index and of which images
    are readable, in every process and any order of requests, but two samples
    show one painting. Each process (every DataLoader worker, and a fresh set of
    workers each epoch unless ``persistent_workers=True``) finds and warns
    about the bad images it meets on its own, and its ``bad_images`` never
    reach the main process.

  If no image can be read at all, ``ValueError``.

Damage that the decoder reads through (e.g. flipped bits inside JPEG data,
which libjpeg decodes with artefacts) cannot be detected and gives a painting.

All sources keep only plain data (paths, tensors, arrays, the user's dataset)
so that they can be pickled and sent to ``DataLoader`` worker processes.
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
from PIL import ExifTags, Image, ImageOps

from . import procedural
from .config import ON_BAD_IMAGE, SidarConfig

__all__ = [
    "IMAGE_EXTENSIONS",
    "CROP_MODES",
    "BadImageWarning",
    "PaintingSize",
    "PaintingSource",
    "ProceduralPaintings",
    "ImageFiles",
    "ImageTooLargeError",
    "MAX_IMAGE_PIXELS",
    "TensorPaintings",
    "ImageList",
    "DatasetPaintings",
    "fit_painting",
    "make_source",
    "tensor_to_uint8",
]

PaintingSize = tuple[int, int]
"""``(height, width)`` of a painting in pixels."""

IMAGE_EXTENSIONS = frozenset({".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp", ".gif"})
"""File extensions (lower case) picked up when a folder is scanned."""

CROP_MODES = ("center", "none")
"""Accepted values of the ``crop`` argument."""


class BadImageWarning(UserWarning):
    """An image could not be read and was skipped (``on_bad_image="skip"``)."""


_WARNED: set[str] = set()
"""Names of the unreadable images this process has warned about: one warning per image and process,
whichever source (or copy of a source) met it. Forked workers inherit it."""


_ROTATING_ORIENTATIONS = frozenset({5, 6, 7, 8})  # EXIF orientations that swap width and height

MAX_IMAGE_PIXELS: int = SidarConfig.max_image_pixels
"""Default pixel budget of an image file (``2**28``, the config field ``max_image_pixels``'s default)."""

JPEG_DRAFT_PIXELS = 1024 * 1024 * 1024 // 4 // 3
"""JPEGs with more pixels than this (89,478,485, Pillow's default decompression-bomb limit, where reduced
decoding started before) are decoded at reduced scale (see "Large images" in the module docstring)."""


# --------------------------------------------------------------------------- validation


def _check_size(size: Any) -> PaintingSize:
    """Return ``size`` as ``(height, width)`` after checking it is two positive ints."""
    try:
        height, width = size
        if isinstance(height, bool) or isinstance(width, bool):
            raise TypeError
        height, width = operator.index(height), operator.index(width)
    except (TypeError, ValueError):
        raise ValueError(f"size must be (height, width), two positive ints; got {size!r}") from None
    if height <= 0 or width <= 0:
        raise ValueError(f"size must be (height, width), two positive ints; got {size!r}")
    return height, width


def _check_index(index: Any, length: int) -> int:
    """Return ``index % length`` after checking ``index`` is an int ``>= 0``."""
    value = operator.index(index)
    if value < 0:
        raise ValueError(f"painting index must be >= 0, got {value}")
    return value % length


def _check_choice(name: str, value: Any, choices: tuple[str, ...]) -> str:
    """Return ``value`` after checking it is one of ``choices`` (the message names argument ``name``)."""
    if value not in choices:
        raise ValueError(f"{name} must be one of {choices}, got {value!r}")
    return value


# --------------------------------------------------------------------------- crop + resample


def _crop_box(image_size: tuple[int, int], size: PaintingSize, crop: str) -> tuple[float, float, float, float]:
    """Box ``(x0, y0, x1, y1)`` in source pixels (floats) that is resampled to ``size``.

    ``image_size`` is Pillow's ``(width, height)``; ``size`` is ``(H, W)``.
    """
    src_w, src_h = image_size
    if crop == "none":
        return 0.0, 0.0, float(src_w), float(src_h)
    height, width = size
    scale = min(src_w / width, src_h / height)
    box_w, box_h = width * scale, height * scale
    x0, y0 = (src_w - box_w) / 2, (src_h - box_h) / 2
    return x0, y0, x0 + box_w, y0 + box_h


def fit_painting(image: Image.Image, size: PaintingSize, crop: str = "center") -> np.ndarray:
    """Crop an RGB image to the aspect of ``size`` and resample it to exactly ``size``.

    Args:
        image: a PIL image in mode ``"RGB"``, of any size.
        size: output ``(H, W)`` in pixels.
        crop: ``"center"`` (largest centred box of aspect ``W / H``, float
            coordinates) or ``"none"`` (stretch the whole image).

    Returns:
        ``(H, W, 3)`` ``uint8`` C-contiguous array. If the image is already
        ``W x H`` its pixels are returned unchanged; otherwise the box is
        resampled with Lanczos (antialiased when downscaling).
    """
    height, width = _check_size(size)
    crop = _check_choice("crop", crop, CROP_MODES)
    if image.mode != "RGB":
        raise ValueError(f"fit_painting expects an RGB image, got mode {image.mode!r}")
    if image.size != (width, height):
        box = _crop_box(image.size, (height, width), crop)
        image = image.resize((width, height), resample=Image.Resampling.LANCZOS, box=box)
    return np.array(image, dtype=np.uint8, order="C")


# --------------------------------------------------------------------------- colour conversion


def _uint16_to_uint8(values: np.ndarray) -> np.ndarray:
    """Scale integer values in ``0..65535`` (clipped) to ``0..255`` with rounding."""
    wide = np.clip(values.astype(np.int64), 0, 65535)
    return ((wide * 255 + 32767) // 65535).astype(np.uint8)


def _float_to_uint8(values: np.ndarray) -> np.ndarray:
    """Map mode-``F`` values to ``uint8``: ``[0, 1]`` data is scaled by 255, else clipped to 0..255."""
    values = np.nan_to_num(values.astype(np.float64), nan=0.0, posinf=255.0, neginf=0.0)
    if values.size and values.min() >= 0.0 and values.max() <= 1.0:
        values = values * 255.0
    return np.rint(np.clip(values, 0.0, 255.0)).astype(np.uint8)


def _grey_to_rgb(grey: np.ndarray) -> Image.Image:
    """``(h, w)`` ``uint8`` array -> PIL RGB image with three equal channels."""
    return Image.fromarray(grey, "L").convert("RGB")


def _to_rgb(image: Image.Image) -> Image.Image:
    """Convert a PIL image of any mode to 8-bit ``"RGB"`` (see module docstring).

    Applies the EXIF orientation first. Alpha is composited over black.
    """
    image = ImageOps.exif_transpose(image)
    if image.mode.startswith("I;16") or image.mode == "I":
        return _grey_to_rgb(_uint16_to_uint8(np.asarray(image)))
    if image.mode == "F":
        return _grey_to_rgb(_float_to_uint8(np.asarray(image)))
    if image.has_transparency_data:
        rgba = np.asarray(image.convert("RGBA"), dtype=np.uint32)
        rgb = (rgba[..., :3] * rgba[..., 3:] + 127) // 255
        return Image.fromarray(rgb.astype(np.uint8), "RGB")
    return image if image.mode == "RGB" else image.convert("RGB")


def tensor_to_uint8(tensor: torch.Tensor, *, batched: bool, name: str = "image tensor",
                     grey: bool = False) -> torch.Tensor:
    """Validate an image tensor and return it as a contiguous CPU ``uint8`` tensor.

    The one conversion of image tensors to 8-bit pixels: painting sources and ``SidarAugment`` use it.

    Args:
        tensor: ``(N, 3, h, w)`` or ``(3, h, w)`` if ``batched``, else
            ``(3, h, w)``; with ``grey``, one channel (``(N, 1, h, w)``,
            ``(1, h, w)``) is accepted too and copied to the three. Float
            values must be finite and in ``[0, 1]`` (converted with
            ``round(x * 255)``); ``uint8`` is taken as is.
        batched: whether a leading batch dimension is allowed.
        name: how error messages name the tensor.
        grey: whether one-channel images are accepted.

    Returns:
        ``uint8`` tensor, ``(N, 3, h, w)`` if ``batched`` (a single image gets
        ``N = 1``), else ``(3, h, w)``.

    Raises:
        ValueError: wrong shape (naming the shapes expected), empty, NaN or
            infinite values, float values outside ``[0, 1]``, or a dtype that
            is neither floating point nor ``uint8``.
    """
    channels = (1, 3) if grey else (3,)
    single = " or ".join(f"({c}, h, w)" for c in reversed(channels))
    expected = f"(N, 3, h, w){' or (N, 1, h, w)' if grey else ''} or {single}" if batched else single
    shape = tuple(tensor.shape)
    if tensor.ndim not in ((3, 4) if batched else (3,)) or shape[-3] not in channels:
        raise ValueError(f"{name} must have shape {expected}, got {shape}")
    if tensor.numel() == 0:
        raise ValueError(f"{name} is empty: shape {shape}")
    tensor = tensor.detach().cpu()
    if tensor.dtype == torch.uint8:
        result = tensor.contiguous()
    elif tensor.is_floating_point():
        tensor = tensor.float()
        if not bool(torch.isfinite(tensor).all()):
            raise ValueError(f"{name} values must be finite, got NaN or infinite values")
        low, high = float(tensor.min()), float(tensor.max())
        if low < 0.0 or high > 1.0:
            raise ValueError(f"{name} float values must be in [0, 1], got range [{low}, {high}]")
        result = (tensor * 255).round().to(torch.uint8)
    else:
        raise ValueError(f"{name} dtype must be a float type or torch.uint8, got {tensor.dtype}")
    result = result.unsqueeze(0) if batched and result.ndim == 3 else result
    return result.expand(*result.shape[:-3], 3, *result.shape[-2:]).contiguous() if result.shape[-3] == 1 else result


def _chw_to_image(tensor: torch.Tensor) -> Image.Image:
    """``(3, h, w)`` ``uint8`` CPU tensor -> PIL RGB image."""
    return Image.fromarray(np.ascontiguousarray(tensor.permute(1, 2, 0).numpy()), "RGB")


# --------------------------------------------------------------------------- file decoding


class ImageTooLargeError(ValueError):
    """An image file's header claims more pixels than the budget ``max_image_pixels`` allows."""


def _check_pixels(image: Image.Image, path: str, max_pixels: int) -> None:
    """Refuse an opened (not yet decoded) image above ``max_pixels``: Pillow has read only its header."""
    pixels = image.width * image.height
    if pixels > max_pixels:
        raise ImageTooLargeError(
            f"image file {path!r} is {image.height} x {image.width} (H x W) = {pixels} pixels, more than "
            f"max_image_pixels={max_pixels} (read from its header; nothing decoded): raise the config field "
            "max_image_pixels to paint with it")


def _draft_large_jpeg(image: Image.Image, size: PaintingSize) -> None:
    """Let a JPEG above :data:`JPEG_DRAFT_PIXELS` decode at 1/2, 1/4 or 1/8 scale, never below ``size``."""
    if image.width * image.height <= JPEG_DRAFT_PIXELS:
        return
    height, width = size
    if image.getexif().get(ExifTags.Base.Orientation) in _ROTATING_ORIENTATIONS:
        height, width = width, height
    image.draft(None, (width, height))  # no-op for formats other than JPEG


def _load_image(path: str | os.PathLike[str], size: PaintingSize, max_pixels: int = MAX_IMAGE_PIXELS) -> Image.Image:
    """Decode an image file to 8-bit RGB (EXIF orientation applied), if its header is within budget.

    Args:
        path: image file.
        size: ``(H, W)`` the image will be resampled to; only used to choose
            the reduced decoding scale of large JPEGs.
        max_pixels: the most pixels (width x height, from the header) decoded.

    Raises:
        FileNotFoundError, PermissionError, IsADirectoryError: from the OS.
        ImageTooLargeError: the header claims more than ``max_pixels`` pixels
            (message has path and size).
        ValueError: the file cannot be decoded (message has path and cause).
    """
    path = os.fspath(path)
    try:
        with Image.open(path) as image:  # reads the header only
            _check_pixels(image, path, max_pixels)
            _draft_large_jpeg(image, size)
            image.load()
            return _to_rgb(image)
    except (FileNotFoundError, PermissionError, IsADirectoryError, ImageTooLargeError):
        raise
    except Image.DecompressionBombError as exc:
        raise ValueError(
            f"cannot decode image file {path!r}: Pillow refuses it ({exc}); PIL.Image.MAX_IMAGE_PIXELS is "
            f"Pillow's own process-wide limit: a program that paints with such images sets it to None, and "
            f"max_image_pixels={max_pixels} decides") from exc
    except Exception as exc:  # Pillow raises many types for corrupt data
        raise ValueError(f"cannot decode image file {path!r}: {type(exc).__name__}: {exc}") from exc


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
        self.crop = _check_choice("crop", crop, CROP_MODES)

    @abc.abstractmethod
    def _image(self, index: int, size: PaintingSize) -> Image.Image:
        """RGB image number ``index`` (``0 <= index < len(self)``) before fitting to ``size``."""

    def painting(self, index: int, size: PaintingSize) -> np.ndarray:
        size = _check_size(size)
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
        self.on_bad_image = _check_choice("on_bad_image", on_bad_image, ON_BAD_IMAGE)
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
        size = _check_size(size)
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
        return _load_image(self.paths[position], size, self.max_pixels)


class TensorPaintings(_ImageSource):
    """Paintings from one image tensor.

    Args:
        images: ``(N, 3, h, w)`` or ``(3, h, w)``; float in ``[0, 1]`` or
            ``uint8``. Stored as a CPU ``uint8`` copy (``round(x * 255)``).
        crop: see :func:`fit_painting`.
    """

    def __init__(self, images: torch.Tensor, *, crop: str = "center") -> None:
        super().__init__(crop)
        self.images = tensor_to_uint8(images, batched=True)

    def __len__(self) -> int:
        return self.images.shape[0]

    def _image(self, index: int, size: PaintingSize) -> Image.Image:
        return _chw_to_image(self.images[index])


class ImageList(_ImageSource):
    """Paintings from a list of ``(3, h, w)`` tensors and/or PIL images (sizes may differ).

    Every item is converted to ``uint8`` RGB when the source is built (PIL
    images with :func:`_to_rgb`, tensors as in :class:`TensorPaintings`) and
    kept as an ``(h, w, 3)`` array.
    """

    def __init__(self, images: Sequence[torch.Tensor | Image.Image], *, crop: str = "center") -> None:
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
            ``(3, h, w)`` tensor, a PIL image, or a tuple/list whose first
            element is one (e.g. ``(image, label)``).
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
    """A ``(3, h, w)`` tensor or PIL image -> PIL RGB image; else ``TypeError``."""
    if isinstance(item, torch.Tensor):
        return _chw_to_image(tensor_to_uint8(item, batched=False, name=f"painting item {position}"))
    if isinstance(item, Image.Image):
        return _to_rgb(item)
    raise TypeError(
        f"painting item {position} must be a (3, h, w) torch.Tensor or a PIL image, got {type(item).__name__}"
    )


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
        height, width = _check_size(size)
        return procedural.paint(np.random.default_rng([self.SEED, _check_index(index, self.count)]), height, width)


# --------------------------------------------------------------------------- make_source


_ACCEPTED = (
    "None (procedural paintings), a folder or image file path (str or os.PathLike), a list/tuple of image "
    "paths, a torch.Tensor of shape (N, 3, h, w) or (3, h, w), a list/tuple of (3, h, w) tensors and/or "
    "PIL images, a PaintingSource, or a dataset with __len__ and __getitem__ whose items are a tensor, "
    "a PIL image, or a tuple starting with one"
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
    if all(isinstance(item, (torch.Tensor, Image.Image)) for item in items):
        return ImageList(items, crop=crop)
    raise TypeError(
        "source list/tuple must hold only image paths or only tensors/PIL images; "
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
        source: ``None``, a path, a list/tuple of paths, tensors or PIL images,
            a tensor, a :class:`PaintingSource`, or an indexable dataset.
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
        ValueError: empty folder/list/tensor/dataset, invalid tensor, invalid
            ``crop`` or ``on_bad_image``.
    """
    crop = _check_choice("crop", crop, CROP_MODES)
    on_bad_image = _check_choice("on_bad_image", on_bad_image, ON_BAD_IMAGE)
    if source is None:
        return ProceduralPaintings()
    if isinstance(source, PaintingSource):
        return source
    if isinstance(source, (str, os.PathLike)):
        return _source_from_path(source, crop, on_bad_image, max_pixels)
    if isinstance(source, torch.Tensor):
        return TensorPaintings(source, crop=crop)
    if isinstance(source, (list, tuple)):
        return _source_from_sequence(source, crop, on_bad_image, max_pixels)
    if _is_dataset(source):
        return DatasetPaintings(source, crop=crop, on_bad_image=on_bad_image)
    raise TypeError(f"source must be one of: {_ACCEPTED}; got {type(source).__name__}")
