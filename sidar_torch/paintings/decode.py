"""Images in, painting pixels out: one path from a file, a PIL image, a tensor or an array to the
``(H, W, 3)`` uint8 RGB painting of an exact size (``docs/paintings.md``: formats, large images).

:func:`fit_painting` crops and resamples a PIL image; :func:`tensor_to_uint8` converts float
``[0, 1]`` or uint8 tensors (painting sources and ``SidarAugment`` both use it) and
:func:`array_to_uint8` NumPy images, channels last as OpenCV and albumentations hand them out, into
such tensors; :func:`load_image`
decodes a file within a pixel budget, the EXIF orientation applied.
"""

from __future__ import annotations

import math
import operator
import os
from typing import Any

import numpy as np
import torch
from PIL import ExifTags, Image, ImageOps

from ..config import SidarConfig

__all__ = ["CROP_MODES", "JPEG_DRAFT_PIXELS", "MAX_IMAGE_PIXELS", "ImageTooLargeError", "PaintingSize", "check_choice",
           "array_to_uint8", "check_size", "chw_to_image", "fit_painting", "load_image", "tensor_to_uint8", "to_rgb"]

PaintingSize = tuple[int, int]
"""``(height, width)`` of a painting in pixels."""

CROP_MODES = ("center", "none")
"""Accepted values of the ``crop`` argument."""


_ROTATING_ORIENTATIONS = frozenset({5, 6, 7, 8})  # EXIF orientations that swap width and height

MAX_IMAGE_PIXELS: int = SidarConfig.max_image_pixels
"""Default pixel budget of an image file (``2**28``, the config field ``max_image_pixels``'s default)."""

JPEG_DRAFT_PIXELS = 1024 * 1024 * 1024 // 4 // 3
"""JPEGs with more pixels than this (89,478,485, Pillow's default decompression-bomb limit, where reduced
decoding started before) are decoded at reduced scale (see "Large images" in the module docstring)."""


def check_size(size: Any) -> PaintingSize:
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


def check_choice(name: str, value: Any, choices: tuple[str, ...]) -> str:
    """Return ``value`` after checking it is one of ``choices`` (the message names argument ``name``)."""
    if value not in choices:
        raise ValueError(f"{name} must be one of {choices}, got {value!r}")
    return value


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
    height, width = check_size(size)
    crop = check_choice("crop", crop, CROP_MODES)
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


def _greyto_rgb(grey: np.ndarray) -> Image.Image:
    """``(h, w)`` ``uint8`` array -> PIL RGB image with three equal channels."""
    return Image.fromarray(grey, "L").convert("RGB")


def to_rgb(image: Image.Image) -> Image.Image:
    """Convert a PIL image of any mode to 8-bit ``"RGB"`` (see module docstring).

    Applies the EXIF orientation first. Alpha is composited over black.
    """
    image = ImageOps.exif_transpose(image)
    if image.mode.startswith("I;16") or image.mode == "I":
        return _greyto_rgb(_uint16_to_uint8(np.asarray(image)))
    if image.mode == "F":
        return _greyto_rgb(_float_to_uint8(np.asarray(image)))
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
        raise ValueError(f"{name} must have shape {expected}, got {shape}{_layout_fix(shape, batched, grey)}")
    if tensor.numel() == 0:
        raise ValueError(f"{name} is empty: shape {shape}")
    tensor = tensor.detach().cpu()
    if tensor.dtype == torch.uint8:
        result = tensor.contiguous()
    elif tensor.is_floating_point():
        tensor = tensor.float()
        low, high = (float(value) for value in torch.aminmax(tensor))  # one pass; a NaN makes both NaN
        if not (math.isfinite(low) and math.isfinite(high)):
            raise ValueError(f"{name} values must be finite, got NaN or infinite values")
        if low < 0.0 or high > 1.0:
            raise ValueError(f"{name} float values must be in [0, 1], got range [{low}, {high}]{_range_fix(low, high)}")
        result = tensor.mul(255).round_().to(torch.uint8)
    else:
        raise ValueError(f"{name} dtype must be a float type or torch.uint8, got {tensor.dtype}")
    result = result.unsqueeze(0) if batched and result.ndim == 3 else result
    return result.expand(*result.shape[:-3], 3, *result.shape[-2:]).contiguous() if result.shape[-3] == 1 else result


def _layout_fix(shape: tuple[int, ...], batched: bool, grey: bool) -> str:
    """The call that turns a tensor of ``shape``, refused by :func:`tensor_to_uint8`, into an accepted
    one, as a hint to end its message with (``""`` when no layout is evident)."""
    if len(shape) in ((3, 4) if batched else (3,)) and shape[-1] in ((1, 3) if grey else (3,)):
        permute = "x.permute(2, 0, 1)" if len(shape) == 3 else "x.permute(0, 3, 1, 2)"
        return f"; channels last (h, w, c), as OpenCV, albumentations and PIL give them? use {permute}"
    if len(shape) == 2:
        return f"; one grey image (h, w)? use {'x[None]' if grey else 'x.expand(3, -1, -1)'}"
    return ""


def _range_fix(low: float, high: float) -> str:
    """What to do with float pixels in ``[low, high]``, outside [0, 1], as a hint for an error message."""
    if low >= 0.0 and 2.0 < high <= 255.0:
        return "; 8-bit values 0..255 as floats? use x / 255 (or pass uint8)"
    if low >= -1.0 and high <= 1.0:
        return "; values in [-1, 1]? use (x + 1) / 2"
    if low < 0.0:
        return "; normalised (x - mean) / std? undo it first: x * std + mean"
    return "; slightly above 1 from arithmetic? clip to [0, 1] (x.clamp(0, 1), np.clip(x, 0, 1))"


def array_to_uint8(array: np.ndarray, *, batched: bool, name: str = "image array") -> torch.Tensor:
    """NumPy image(s), channels last, as :func:`tensor_to_uint8` returns tensors.

    Args:
        array: one RGB image ``(h, w, 3)`` or grey image ``(h, w)`` / ``(h, w, 1)`` (copied to the three
            channels), or if ``batched`` also ``(N, h, w, 3)`` / ``(N, h, w, 1)``: channels last, as
            OpenCV, albumentations and ``np.asarray(pil_image)`` give them (RGB: OpenCV's ``cv2.imread``
            gives BGR, convert it with ``cv2.cvtColor(x, cv2.COLOR_BGR2RGB)``). ``uint8``, or any float
            dtype with values in ``[0, 1]`` (``round(x * 255)``).
        batched: whether a leading batch dimension is allowed.
        name: how error messages name the array.

    Returns:
        CPU ``uint8`` tensor ``(N, 3, h, w)`` if ``batched`` (a single image gets ``N = 1``), else ``(3, h, w)``.

    Raises:
        ValueError: another shape or dtype (the message says which call fixes a channels-first
            array or 16-bit pixels), empty, NaN or infinite values, float values outside ``[0, 1]``.
    """
    shape = array.shape
    if array.ndim == 2:
        array = array[:, :, None]
    if array.ndim not in ((3, 4) if batched else (3,)) or array.shape[-1] not in (1, 3):
        expected = "(h, w, 3), (h, w) or (h, w, 1)" + (", or (N, h, w, 3) or (N, h, w, 1)" if batched else "")
        fix = ""
        if array.ndim in (3, 4) and array.shape[-3] in (1, 3):
            transpose = "x.transpose(1, 2, 0)" if array.ndim == 3 else "x.transpose(0, 2, 3, 1)"
            fix = f"; channels first (c, h, w)? use {transpose} or pass torch.from_numpy(x)"
        elif batched and array.ndim == 3:
            fix = "; a batch of grey images (N, h, w)? use x[..., None]"
        raise ValueError(f"{name} must have shape {expected} (channels last), got {shape}{fix}")
    if array.dtype != np.uint8 and not np.issubdtype(array.dtype, np.floating):
        fix = f"; {array.dtype.itemsize * 8}-bit integers? use x / {np.iinfo(array.dtype).max}" \
            if np.issubdtype(array.dtype, np.integer) else ""
        raise ValueError(f"{name} dtype must be uint8 or a float type with values in [0, 1], got {array.dtype}{fix}")
    native = np.ascontiguousarray(array, dtype=array.dtype.newbyteorder("="))  # torch takes native byte order only
    return tensor_to_uint8(torch.from_numpy(native).movedim(-1, -3), batched=batched, name=name, grey=True)


def chw_to_image(tensor: torch.Tensor) -> Image.Image:
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


def load_image(path: str | os.PathLike[str], size: PaintingSize, max_pixels: int = MAX_IMAGE_PIXELS) -> Image.Image:
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
            return to_rgb(image)
    except (FileNotFoundError, PermissionError, IsADirectoryError, ImageTooLargeError):
        raise
    except Image.DecompressionBombError as exc:
        raise ValueError(
            f"cannot decode image file {path!r}: Pillow refuses it ({exc}); PIL.Image.MAX_IMAGE_PIXELS is "
            f"Pillow's own process-wide limit: a program that paints with such images sets it to None, and "
            f"max_image_pixels={max_pixels} decides") from exc
    except Exception as exc:  # Pillow raises many types for corrupt data
        raise ValueError(f"cannot decode image file {path!r}: {type(exc).__name__}: {exc}") from exc
