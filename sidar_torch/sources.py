"""Painting sources: the images used as textures.

A *painting source* gives painting number ``i`` at an exact output size as an
``(H, W, 3)`` ``uint8`` RGB array. :func:`make_source` turns whatever the user
passes as ``source`` into a :class:`PaintingSource`:

* ``None`` -> :class:`ProceduralPaintings`, a deterministic generator of
  synthetic paintings, so that the package runs with no data at all;
* a folder -> :class:`ImageFiles` over every image file below it (recursively,
  following symbolic links to folders but not links that loop back to a folder
  above them; extensions in :data:`IMAGE_EXTENSIONS`, case-insensitive), sorted
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
Files are decoded only when a painting is requested. Images with more pixels
than ``PIL.Image.MAX_IMAGE_PIXELS`` (Pillow's decompression-bomb limit) are
not rejected: the (process-global) limit is lifted while a file is opened
and decoded, and restored afterwards. Such an image triggers a
:class:`UserWarning`; if it is a JPEG it is decoded directly at 1/2, 1/4 or
1/8 scale (libjpeg DCT scaling via ``Image.draft``) but never below the
output size, and the crop box is computed on the reduced image (the
reduction rounds image sizes up, which can shift the crop by less than one
reduced pixel). Other formats are decoded at full size, so a truly huge
non-JPEG file needs the memory for all its pixels.

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

Files and dataset items are read only when their painting is requested, so a
bad one is found then: a truncated or corrupt file, a non-image file with an
image extension, a file without read permission or deleted since the folder
was listed, a dataset item whose loading raises or that is not an image. The
``on_bad_image`` argument (``SidarConfig.on_bad_image``) decides:

* ``"raise"`` (default): the error propagates. Files give ``ValueError``
  ("cannot decode image file '<path>': <Pillow's reason>") or the OS error
  (``PermissionError``, ``FileNotFoundError``), which names the file; dataset
  items give whatever the dataset raised, or ``TypeError`` / ``ValueError``
  naming the item if it is not a valid image.
* ``"skip"``: painting ``i`` is the first readable image of ``i, i + 1, ...``
  (wrapping around). Each unreadable image gives one :class:`BadImageWarning`
  naming it and the error, and is recorded in the source's ``bad_images``
  (``{name: reason}``; the name is the file's absolute path or ``"dataset item <i>"``)
  so that it is not read again; ``len(bad_images)`` is the count. A process
  warns once per image, whichever source met it. The painting an index shows
  depends only on the index and on which images are readable, not on the
  order of requests or on the process. Each DataLoader worker keeps its own
  ``bad_images``, which never reach the main process: to learn which images
  are unreadable there (and keep workers silent), call ``source.scan()``
  before iterating or exporting (``SidarDataset(...).source.scan()``). If no
  image can be read at all, ``ValueError``.

Damage that the decoder reads through (e.g. flipped bits inside JPEG data,
which libjpeg decodes with artefacts) cannot be detected and gives a painting.

All sources keep only plain data (paths, tensors, arrays, the user's dataset)
so that they can be pickled and sent to ``DataLoader`` worker processes.
"""

from __future__ import annotations

import abc
import contextlib
import operator
import os
import warnings
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import torch
from PIL import ExifTags, Image, ImageOps

from . import procedural
from .config import ON_BAD_IMAGE

__all__ = [
    "IMAGE_EXTENSIONS",
    "CROP_MODES",
    "BadImageWarning",
    "PaintingSize",
    "PaintingSource",
    "ProceduralPaintings",
    "ImageFiles",
    "TensorPaintings",
    "ImageList",
    "DatasetPaintings",
    "fit_painting",
    "make_source",
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


def _tensor_to_uint8(tensor: torch.Tensor, *, batched: bool, name: str = "image tensor") -> torch.Tensor:
    """Validate an image tensor and return it as a contiguous CPU ``uint8`` tensor.

    Args:
        tensor: ``(N, 3, h, w)`` or ``(3, h, w)`` if ``batched``, else
            ``(3, h, w)``. Float values must be finite and in ``[0, 1]``
            (converted with ``round(x * 255)``); ``uint8`` is taken as is.
        batched: whether a leading batch dimension is allowed.
        name: how error messages name the tensor.

    Returns:
        ``uint8`` tensor, ``(N, 3, h, w)`` if ``batched`` (a single image gets
        ``N = 1``), else ``(3, h, w)``.
    """
    expected = "(N, 3, h, w) or (3, h, w)" if batched else "(3, h, w)"
    shape = tuple(tensor.shape)
    if tensor.ndim not in ((3, 4) if batched else (3,)) or shape[-3] != 3:
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
    return result.unsqueeze(0) if batched and result.ndim == 3 else result


def _chw_to_image(tensor: torch.Tensor) -> Image.Image:
    """``(3, h, w)`` ``uint8`` CPU tensor -> PIL RGB image."""
    return Image.fromarray(np.ascontiguousarray(tensor.permute(1, 2, 0).numpy()), "RGB")


# --------------------------------------------------------------------------- file decoding


@contextlib.contextmanager
def _pixel_limit_lifted() -> Iterator[int | None]:
    """Disable Pillow's decompression-bomb check; yield the previous limit.

    The limit is process-global; it is restored on exit.
    """
    limit = Image.MAX_IMAGE_PIXELS
    Image.MAX_IMAGE_PIXELS = None
    try:
        yield limit
    finally:
        Image.MAX_IMAGE_PIXELS = limit


def _draft_large_image(image: Image.Image, path: str, size: PaintingSize, limit: int) -> None:
    """Warn about an image above the pixel limit and let JPEGs decode at reduced scale."""
    warnings.warn(
        f"{path}: {image.width}x{image.height} pixels exceeds PIL.Image.MAX_IMAGE_PIXELS={limit}; "
        "decoding anyway (JPEG at reduced scale, no smaller than the output size)",
        UserWarning,
        stacklevel=2,
    )
    height, width = size
    if image.getexif().get(ExifTags.Base.Orientation) in _ROTATING_ORIENTATIONS:
        height, width = width, height
    image.draft(None, (width, height))  # no-op for formats other than JPEG


def _load_image(path: str | os.PathLike[str], size: PaintingSize) -> Image.Image:
    """Decode an image file to 8-bit RGB (EXIF orientation applied).

    Args:
        path: image file.
        size: ``(H, W)`` the image will be resampled to; only used to choose
            the reduced decoding scale of JPEGs above Pillow's pixel limit.

    Raises:
        FileNotFoundError, PermissionError, IsADirectoryError: from the OS.
        ValueError: the file cannot be decoded (message has path and cause).
    """
    path = os.fspath(path)
    try:
        with _pixel_limit_lifted() as limit, Image.open(path) as image:
            if limit is not None and image.width * image.height > limit:
                _draft_large_image(image, path, size, limit)
            image.load()
            return _to_rgb(image)
    except (FileNotFoundError, PermissionError, IsADirectoryError):
        raise
    except Exception as exc:  # Pillow raises many types for corrupt data
        raise ValueError(f"cannot decode image file {path!r}: {type(exc).__name__}: {exc}") from exc


def _list_images(folder: Path) -> list[str]:
    """Every image file below ``folder`` (recursive, following symbolic links to folders), sorted by
    relative POSIX path.

    A linked folder is listed once per path that reaches it, but a link back to a folder that
    contains it (a loop) is not followed. Unreadable folders raise the OS error (e.g.
    ``PermissionError``), which names the folder.
    """

    def fail(error: OSError) -> None:
        raise error

    found: list[tuple[str, str]] = []
    for dirpath, dirnames, filenames in os.walk(folder, onerror=fail, followlinks=True):
        # The real folders on the way from ``folder`` down to here: a subfolder that is one of them
        # would walk the same tree again, forever.
        steps = Path(os.path.relpath(dirpath, folder)).parts
        above = {os.path.realpath(os.path.join(folder, *steps[:depth])) for depth in range(len(steps) + 1)}
        dirnames[:] = [d for d in dirnames if os.path.realpath(os.path.join(dirpath, d)) not in above]
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


class _ReadingSource(_ImageSource):
    """An image source that reads each image only when its painting is requested, so reading can fail.

    What happens to an image that cannot be read is ``on_bad_image``'s choice
    (see "Bad input" in the module docstring); the images skipped so far are
    in ``bad_images``, ``{name: "<error type>: <message>"}``.
    """

    def __init__(self, crop: str, on_bad_image: str) -> None:
        super().__init__(crop)
        self.on_bad_image = _check_choice("on_bad_image", on_bad_image, ON_BAD_IMAGE)
        self.bad_images: dict[str, str] = {}

    def scan(self, size: PaintingSize = (64, 64)) -> dict[str, str]:
        """Read every image once (at ``size``, a cheap draft for JPEGs) and record the unreadable ones.

        Call it in the main process before handing the dataset to DataLoader workers: the workers
        get the source with ``bad_images`` filled, so they neither read nor warn about those files
        again, and the main process knows them (a worker's own ``bad_images`` never reaches it).

        Returns:
            ``bad_images``: ``{name: "<error type>: <message>"}`` of every image that cannot be read.
        """
        size = _check_size(size)
        for index in range(len(self)):
            name = self._name(index)
            if name in self.bad_images:
                continue
            try:
                self._read(index, size)
            except Exception as exc:  # as in _image
                self._record_bad(name, exc)
        return dict(self.bad_images)

    def _record_bad(self, name: str, exc: Exception) -> None:
        """Remember that image ``name`` cannot be read; warn unless this process warned about it before."""
        self.bad_images[name] = f"{type(exc).__name__}: {exc}"
        if name not in _WARNED:
            _WARNED.add(name)
            warnings.warn(f"on_bad_image='skip': skipping unreadable image {name}: {self.bad_images[name]}",
                          BadImageWarning, stacklevel=4)

    @abc.abstractmethod
    def _read(self, index: int, size: PaintingSize) -> Image.Image:
        """Read image ``index`` as in :meth:`_image`, raising whatever reading raises."""

    @abc.abstractmethod
    def _name(self, index: int) -> str:
        """How warnings and errors name image ``index``."""

    def _image(self, index: int, size: PaintingSize) -> Image.Image:
        if self.on_bad_image == "raise":
            return self._read(index, size)
        for offset in range(len(self)):
            candidate = (index + offset) % len(self)
            name = self._name(candidate)
            if name in self.bad_images:
                continue
            try:
                return self._read(candidate, size)
            except Exception as exc:  # Pillow and users' datasets raise many types for bad data
                self._record_bad(name, exc)
        name = self._name(index)
        raise ValueError(
            f"on_bad_image='skip', but none of the {len(self)} images of this {type(self).__name__} can be read; "
            f"{name}: {self.bad_images[name]}"
        )


class ImageFiles(_ReadingSource):
    """Paintings read lazily from image files, in the given order.

    Args:
        paths: image files; they are opened only in :meth:`painting`.
        crop: see :func:`fit_painting`.
        on_bad_image: ``"raise"`` or ``"skip"``, for a file that cannot be
            read (see "Bad input" in the module docstring).

    With ``"raise"``, a file that cannot be decoded raises ``ValueError``
    naming it and the cause; a missing or unreadable one raises the OS error
    (``FileNotFoundError``, ``PermissionError``), which names it too.
    """

    def __init__(
        self, paths: Sequence[str | os.PathLike[str]], *, crop: str = "center", on_bad_image: str = "raise"
    ) -> None:
        super().__init__(crop, on_bad_image)
        self.paths = tuple(os.path.abspath(path) for path in paths)
        if not self.paths:
            raise ValueError("ImageFiles needs at least one path, got an empty list")

    def __len__(self) -> int:
        return len(self.paths)

    def _name(self, index: int) -> str:
        return self.paths[index]

    def _read(self, index: int, size: PaintingSize) -> Image.Image:
        return _load_image(self.paths[index], size)


class TensorPaintings(_ImageSource):
    """Paintings from one image tensor.

    Args:
        images: ``(N, 3, h, w)`` or ``(3, h, w)``; float in ``[0, 1]`` or
            ``uint8``. Stored as a CPU ``uint8`` copy (``round(x * 255)``).
        crop: see :func:`fit_painting`.
    """

    def __init__(self, images: torch.Tensor, *, crop: str = "center") -> None:
        super().__init__(crop)
        self.images = _tensor_to_uint8(images, batched=True)

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
        super().__init__(crop, on_bad_image)
        if len(dataset) == 0:
            raise ValueError("source dataset is empty")
        self.dataset = dataset

    def __len__(self) -> int:
        return len(self.dataset)

    def _name(self, index: int) -> str:
        return f"dataset item {index}"

    def _read(self, index: int, size: PaintingSize) -> Image.Image:
        item = self.dataset[index]
        if isinstance(item, (tuple, list)) and item:
            item = item[0]
        return _item_to_image(item, index)


def _item_to_image(item: Any, position: int) -> Image.Image:
    """A ``(3, h, w)`` tensor or PIL image -> PIL RGB image; else ``TypeError``."""
    if isinstance(item, torch.Tensor):
        return _chw_to_image(_tensor_to_uint8(item, batched=False, name=f"painting item {position}"))
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


def _source_from_path(path: str | os.PathLike[str], crop: str, on_bad_image: str) -> ImageFiles:
    if not os.path.isdir(path):
        _check_files([path])
        return ImageFiles([path], crop=crop, on_bad_image=on_bad_image)
    files = _list_images(Path(path))
    if not files:
        raise ValueError(
            f"no image files ({', '.join(sorted(IMAGE_EXTENSIONS))}) found in folder {os.fspath(path)!r} or below"
        )
    return ImageFiles(files, crop=crop, on_bad_image=on_bad_image)


def _source_from_sequence(items: Sequence[Any], crop: str, on_bad_image: str) -> PaintingSource:
    if len(items) == 0:
        raise ValueError("source is an empty list/tuple")
    if all(isinstance(item, (str, os.PathLike)) for item in items):
        _check_files(items)
        return ImageFiles(items, crop=crop, on_bad_image=on_bad_image)
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


def make_source(source: Any, *, crop: str = "center", on_bad_image: str = "raise") -> PaintingSource:
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
        return _source_from_path(source, crop, on_bad_image)
    if isinstance(source, torch.Tensor):
        return TensorPaintings(source, crop=crop)
    if isinstance(source, (list, tuple)):
        return _source_from_sequence(source, crop, on_bad_image)
    if _is_dataset(source):
        return DatasetPaintings(source, crop=crop, on_bad_image=on_bad_image)
    raise TypeError(f"source must be one of: {_ACCEPTED}; got {type(source).__name__}")
