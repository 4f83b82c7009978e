"""Painting sources: the images used as textures.

A *painting source* gives painting number ``i`` at an exact output size as an
``(H, W, 3)`` ``uint8`` RGB array. :func:`make_source` turns whatever the user
passes as ``source`` into a :class:`PaintingSource`:

* ``None`` -> :class:`ProceduralPaintings`, a deterministic generator of
  synthetic paintings, so that the package runs with no data at all;
* a folder -> :class:`ImageFiles` over every image file below it (recursively;
  extensions in :data:`IMAGE_EXTENSIONS`, case-insensitive), sorted by their
  relative POSIX path so that the order is the same on every machine;
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
from PIL import ExifTags, Image, ImageDraw, ImageOps

__all__ = [
    "IMAGE_EXTENSIONS",
    "CROP_MODES",
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


def _check_crop(crop: str) -> str:
    if crop not in CROP_MODES:
        raise ValueError(f"crop must be one of {CROP_MODES}, got {crop!r}")
    return crop


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
    crop = _check_crop(crop)
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


def _tensor_to_uint8(tensor: torch.Tensor, *, batched: bool) -> torch.Tensor:
    """Validate an image tensor and return it as a contiguous CPU ``uint8`` tensor.

    Args:
        tensor: ``(N, 3, h, w)`` or ``(3, h, w)`` if ``batched``, else
            ``(3, h, w)``. Float values must be finite and in ``[0, 1]``
            (converted with ``round(x * 255)``); ``uint8`` is taken as is.
        batched: whether a leading batch dimension is allowed.

    Returns:
        ``uint8`` tensor, ``(N, 3, h, w)`` if ``batched`` (a single image gets
        ``N = 1``), else ``(3, h, w)``.
    """
    expected = "(N, 3, h, w) or (3, h, w)" if batched else "(3, h, w)"
    shape = tuple(tensor.shape)
    if tensor.ndim not in ((3, 4) if batched else (3,)) or shape[-3] != 3:
        raise ValueError(f"image tensor must have shape {expected}, got {shape}")
    if tensor.numel() == 0:
        raise ValueError(f"image tensor is empty: shape {shape}")
    tensor = tensor.detach().cpu()
    if tensor.dtype == torch.uint8:
        result = tensor.contiguous()
    elif tensor.is_floating_point():
        tensor = tensor.float()
        if not bool(torch.isfinite(tensor).all()):
            raise ValueError("image tensor contains NaN or infinite values")
        low, high = float(tensor.min()), float(tensor.max())
        if low < 0.0 or high > 1.0:
            raise ValueError(f"float image tensor values must be in [0, 1], got range [{low}, {high}]")
        result = (tensor * 255).round().to(torch.uint8)
    else:
        raise ValueError(f"image tensor dtype must be a float type or torch.uint8, got {tensor.dtype}")
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
    """Every image file below ``folder`` (recursive), sorted by relative POSIX path.

    Unreadable folders raise the OS error (e.g. ``PermissionError``), which
    names the folder.
    """

    def fail(error: OSError) -> None:
        raise error

    found: list[tuple[str, str]] = []
    for dirpath, _, filenames in os.walk(folder, onerror=fail):
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
        self.crop = _check_crop(crop)

    @abc.abstractmethod
    def _image(self, index: int, size: PaintingSize) -> Image.Image:
        """RGB image number ``index`` (``0 <= index < len(self)``) before fitting to ``size``."""

    def painting(self, index: int, size: PaintingSize) -> np.ndarray:
        size = _check_size(size)
        return fit_painting(self._image(_check_index(index, len(self)), size), size, self.crop)


class ImageFiles(_ImageSource):
    """Paintings read lazily from image files, in the given order.

    Args:
        paths: image files; they are opened only in :meth:`painting`.
        crop: see :func:`fit_painting`.

    A missing or undecodable file raises ``FileNotFoundError`` or
    ``ValueError`` (with the path) when its painting is requested.
    """

    def __init__(self, paths: Sequence[str | os.PathLike[str]], *, crop: str = "center") -> None:
        super().__init__(crop)
        self.paths = tuple(os.fspath(path) for path in paths)
        if not self.paths:
            raise ValueError("ImageFiles needs at least one path, got an empty list")

    def __len__(self) -> int:
        return len(self.paths)

    def _image(self, index: int, size: PaintingSize) -> Image.Image:
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


class DatasetPaintings(_ImageSource):
    """Paintings from an indexable dataset, read lazily.

    Args:
        dataset: object with ``__len__`` and ``__getitem__``; item ``i`` is a
            ``(3, h, w)`` tensor, a PIL image, or a tuple/list whose first
            element is one (e.g. ``(image, label)``).
        crop: see :func:`fit_painting`.

    The dataset itself must be picklable for use with ``DataLoader`` workers.
    """

    def __init__(self, dataset: Any, *, crop: str = "center") -> None:
        super().__init__(crop)
        if len(dataset) == 0:
            raise ValueError("source dataset is empty")
        self.dataset = dataset

    def __len__(self) -> int:
        return len(self.dataset)

    def _image(self, index: int, size: PaintingSize) -> Image.Image:
        item = self.dataset[index]
        if isinstance(item, (tuple, list)) and item:
            item = item[0]
        return _item_to_image(item, index)


def _item_to_image(item: Any, position: int) -> Image.Image:
    """A ``(3, h, w)`` tensor or PIL image -> PIL RGB image; else ``TypeError``."""
    if isinstance(item, torch.Tensor):
        return _chw_to_image(_tensor_to_uint8(item, batched=False))
    if isinstance(item, Image.Image):
        return _to_rgb(item)
    raise TypeError(
        f"painting item {position} must be a (3, h, w) torch.Tensor or a PIL image, got {type(item).__name__}"
    )


# --------------------------------------------------------------------------- procedural paintings


def _vivid_colors(rng: np.random.Generator, count: int) -> np.ndarray:
    """``(count, 3)`` float RGB colours in ``0..255`` from random hue, saturation and value."""
    hue = rng.random(count)
    sat = rng.uniform(0.35, 1.0, count)
    val = rng.uniform(0.3, 1.0, count)
    k = (np.array([5.0, 3.0, 1.0]) + hue[:, None] * 6.0) % 6.0
    rgb = val[:, None] * (1.0 - sat[:, None] * np.clip(np.minimum(k, 4.0 - k), 0.0, 1.0))
    return rgb * 255.0


def _pick_colors(rng: np.random.Generator, palette: np.ndarray, count: int, spread: float) -> np.ndarray:
    """``(count, 3)`` ``uint8`` colours: random palette entries, each channel shifted by up to ``spread``."""
    colors = palette[rng.integers(len(palette), size=count)] + rng.uniform(-spread, spread, (count, 3))
    return np.clip(colors, 0, 255).round().astype(np.uint8)


def _pick_color(rng: np.random.Generator, palette: np.ndarray, spread: float) -> tuple[int, ...]:
    """One colour of :func:`_pick_colors` as a tuple for ``ImageDraw``."""
    return tuple(_pick_colors(rng, palette, 1, spread)[0].tolist())


def _upsampled_noise(values: np.ndarray, width: int, height: int) -> np.ndarray:
    """Bicubic upsampling of a small float grid to ``(height, width)`` float32, aligned to the image."""
    grid = Image.fromarray(values.astype(np.float32), "F")
    return np.asarray(grid.resize((width, height), Image.Resampling.BICUBIC))


class ProceduralPaintings(PaintingSource):
    """Deterministic synthetic paintings: the built-in default source.

    Each painting is layered: a smooth bicubic colour field, 8-19 filled
    ellipses, polygons and rotated rectangles (random colours from a
    per-painting palette, alpha 90..255), 6-14 opaque multi-bristle brush
    strokes along cubic Bezier curves, then the levels are compressed to
    28..228 and grey value noise is added at three scales: two size-relative
    octaves and a grain of 2-pixel cells (see :func:`_add_texture`), so that
    no region of about 8x8 pixels is flat. All geometry is relative to the
    output size, so one index at two sizes shows the same painting; only the
    grain depends on the pixel grid. Takes about 11 ms for 512x384 on one
    CPU core.

    ``painting(i, size)`` is a pure function of ``(i % count, size)``: it uses
    its own ``numpy.random.default_rng([0x5EED, i % count])``.

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
        rng = np.random.default_rng([self.SEED, _check_index(index, self.count)])
        palette = _vivid_colors(rng, 6)
        grid_h, grid_w = rng.integers(2, 5, size=2)
        background = _pick_colors(rng, palette, grid_h * grid_w, 40).reshape(grid_h, grid_w, 3)
        canvas = Image.fromarray(background, "RGB").resize((width, height), Image.Resampling.BICUBIC)
        draw = ImageDraw.Draw(canvas, "RGBA")  # RGBA fills are alpha-blended onto the RGB canvas
        scale = float(np.sqrt(width * height))
        _draw_shapes(draw, rng, palette, width, height, scale)
        _draw_strokes(draw, rng, palette, width, height, scale)
        return _add_texture(canvas, rng)


def _draw_shapes(
    draw: ImageDraw.ImageDraw, rng: np.random.Generator, palette: np.ndarray, width: int, height: int, scale: float
) -> None:
    """Translucent ellipses, star-like polygons and rotated rectangles, largest first."""
    count = int(rng.integers(8, 20))
    radii = np.sort(np.exp(rng.uniform(np.log(0.03), np.log(0.35), count)))[::-1] * scale
    for radius in radii:
        cx, cy = rng.uniform(-0.1, 1.1, 2) * (width, height)
        fill = (*_pick_color(rng, palette, 30), int(rng.integers(90, 256)))
        kind = rng.integers(3)
        if kind == 0:
            rx, ry = radius * rng.uniform(0.4, 1.0, 2)
            draw.ellipse((cx - rx, cy - ry, cx + rx, cy + ry), fill=fill)
            continue
        if kind == 1:
            corners = int(rng.integers(3, 8))
            angles = np.sort(rng.uniform(0, 2 * np.pi, corners))
            lengths = radius * rng.uniform(0.35, 1.0, corners)
        else:
            half_w, half_h = radius * rng.uniform(0.3, 1.0, 2)
            corner = np.arctan2(half_h, half_w)
            angles = rng.uniform(0, np.pi) + np.array([corner, np.pi - corner, np.pi + corner, -corner])
            lengths = np.full(4, np.hypot(half_w, half_h))
        points = np.stack([cx + lengths * np.cos(angles), cy + lengths * np.sin(angles)], axis=1)
        draw.polygon(points.ravel().tolist(), fill=fill)


def _draw_strokes(
    draw: ImageDraw.ImageDraw, rng: np.random.Generator, palette: np.ndarray, width: int, height: int, scale: float
) -> None:
    """Opaque brush strokes: parallel bristle lines of slightly different colours along Bezier curves."""
    t = np.linspace(0.0, 1.0, 20)[:, None]
    bernstein = np.hstack([(1 - t) ** 3, 3 * t * (1 - t) ** 2, 3 * t**2 * (1 - t), t**3])  # (20, 4)
    offsets = np.linspace(-0.5, 0.5, 4)
    for _ in range(int(rng.integers(6, 15))):
        start = rng.uniform(-0.05, 1.05, 2)
        controls = start + np.cumsum(rng.normal(0.0, 0.12, (4, 2)), axis=0)
        curve = bernstein @ (controls * (width, height))  # (20, 2) pixels
        tangent = np.gradient(curve, axis=0)
        normal = np.stack([-tangent[:, 1], tangent[:, 0]], axis=1)
        normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-9)
        stroke_width = scale * np.exp(rng.uniform(np.log(0.012), np.log(0.06)))
        bristle_width = max(1, round(stroke_width / len(offsets) * 1.6))
        shades = _pick_colors(rng, palette[rng.integers(len(palette))][None], len(offsets), 35)
        for offset, shade in zip(offsets, shades):
            points = curve + offset * stroke_width * normal
            draw.line(points.ravel().tolist(), fill=tuple(shade.tolist()), width=bristle_width, joint="curve")


_COMPRESS_LEVELS = [28 + (200 * level + 127) // 255 for level in range(256)] * 3  # RGB lookup table 0..255 -> 28..228


def _add_texture(canvas: Image.Image, rng: np.random.Generator) -> np.ndarray:
    """Compress the canvas to levels 28..228 and add grey noise at three scales.

    The noise is the sum of two size-relative octaves (12x16 and 48x64 grids,
    up to +-18 and +-10 levels) and a grain of 2-pixel cells (up to +-14
    levels), all bicubically interpolated.

    Args:
        canvas: RGB image of the output size.

    Returns:
        ``(H, W, 3)`` ``uint8`` C-contiguous array.
    """
    width, height = canvas.size
    half = (width // 2 + 1, height // 2 + 1)
    coarse = _upsampled_noise(rng.uniform(-18, 18, (12, 16)), *half)
    medium = _upsampled_noise(rng.uniform(-10, 10, (48, 64)), *half)
    grain = rng.uniform(-14, 14, (half[1], half[0]))
    noise = _upsampled_noise(coarse + medium + grain, width, height).round().astype(np.int16)
    out = np.asarray(canvas.point(_COMPRESS_LEVELS), dtype=np.int16) + noise[..., None]
    return np.clip(out, 0, 255).astype(np.uint8)


# --------------------------------------------------------------------------- make_source


_ACCEPTED = (
    "None (procedural paintings), a folder or image file path (str or os.PathLike), a list/tuple of image "
    "paths, a torch.Tensor of shape (N, 3, h, w) or (3, h, w), a list/tuple of (3, h, w) tensors and/or "
    "PIL images, a PaintingSource, or a dataset with __len__ and __getitem__ whose items are a tensor, "
    "a PIL image, or a tuple starting with one"
)


def _source_from_path(path: str | os.PathLike[str], crop: str) -> ImageFiles:
    if not os.path.isdir(path):
        _check_files([path])
        return ImageFiles([path], crop=crop)
    files = _list_images(Path(path))
    if not files:
        raise ValueError(
            f"no image files ({', '.join(sorted(IMAGE_EXTENSIONS))}) found in folder {os.fspath(path)!r} or below"
        )
    return ImageFiles(files, crop=crop)


def _source_from_sequence(items: Sequence[Any], crop: str) -> PaintingSource:
    if len(items) == 0:
        raise ValueError("source is an empty list/tuple")
    if all(isinstance(item, (str, os.PathLike)) for item in items):
        _check_files(items)
        return ImageFiles(items, crop=crop)
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


def make_source(source: Any, *, crop: str = "center") -> PaintingSource:
    """Build the painting source for ``source`` (see the module docstring for the accepted kinds).

    Args:
        source: ``None``, a path, a list/tuple of paths, tensors or PIL images,
            a tensor, a :class:`PaintingSource`, or an indexable dataset.
        crop: ``"center"`` or ``"none"``, used by image-backed sources built
            here (ignored for ``None`` and for an existing source).

    Raises:
        TypeError: ``source`` is of no accepted kind.
        FileNotFoundError: a path does not exist.
        PermissionError: a folder cannot be read.
        ValueError: empty folder/list/tensor, invalid tensor, invalid ``crop``.
    """
    crop = _check_crop(crop)
    if source is None:
        return ProceduralPaintings()
    if isinstance(source, PaintingSource):
        return source
    if isinstance(source, (str, os.PathLike)):
        return _source_from_path(source, crop)
    if isinstance(source, torch.Tensor):
        return TensorPaintings(source, crop=crop)
    if isinstance(source, (list, tuple)):
        return _source_from_sequence(source, crop)
    if _is_dataset(source):
        return DatasetPaintings(source, crop=crop)
    raise TypeError(f"source must be one of: {_ACCEPTED}; got {type(source).__name__}")
