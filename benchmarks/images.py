"""The 8-bit images the realism measures read: the paper generator's sequences on disk, our sample
tensors as arrays, their colour (sRGB, luminance) and where a view sees the painting.

Shared by ``benchmarks.realism`` and ``benchmarks.blur`` (each uses the other's measures, so what both
need lives here and neither imports the other for it). Homographies follow Kornia's convention
(pixel centres at integers, top-left pixel at (0, 0)) and map label-frame (view 0) pixels to a view's.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image
from scipy import ndimage

from benchmarks.exposure import LUMA

__all__ = ["REGION_MARGIN", "anchor_sequences", "inverse_map", "luminance", "painting_region", "read_rgb",
           "srgb_to_linear", "to_uint8", "warp_label"]

REGION_MARGIN = 2
"""Pixels by which the painting region is shrunk (Blender's mask edge is antialiased and the
renderers' coverage rules differ at the plane's border)."""


def read_rgb(path: Path) -> np.ndarray:
    """The image at ``path`` as ``(H, W, 3)`` uint8 RGB."""
    return np.asarray(Image.open(path).convert("RGB"))


def anchor_sequences(folder: Path) -> list[Path]:
    """The sequence folders below ``folder`` (those holding a ``gt.png``), sorted by name."""
    found = sorted(p.parent for p in folder.glob("*/gt.png"))
    if not found:
        raise SystemExit(f"--anchors {str(folder)!r}: no sequence folders (with gt.png) in it")
    return found


def to_uint8(images: Any) -> np.ndarray:
    """``(N, 3, H, W)`` float tensors in [0, 1] to ``(N, H, W, 3)`` uint8 (exact for 8-bit renders)."""
    return (images.permute(0, 2, 3, 1).numpy() * 255).round().astype(np.uint8)


def srgb_to_linear(srgb: np.ndarray) -> np.ndarray:
    """8-bit sRGB ``(..., 3)`` uint8 to linear light float64 in [0, 1] (exact piecewise curve)."""
    c = np.asarray(srgb, np.float64) / 255.0
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def luminance(views: np.ndarray) -> np.ndarray:
    """Rec. 709 luminance ``(...)`` in linear light [0, 1] of 8-bit sRGB ``(..., 3)``."""
    return srgb_to_linear(views) @ LUMA


def inverse_map(H: np.ndarray, size: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Where each pixel of an ``size = (H, W)`` view comes from in the label frame.

    Args:
        H: ``(3, 3)`` homography mapping label-frame (view 0) pixels to this view's pixels.

    Returns:
        ``x, y`` ``(H, W)`` float64 label-frame coordinates (NaN where the ray misses: w <= 0).
    """
    h, w = size
    v, u = np.mgrid[0:h, 0:w].astype(np.float64)
    p = np.linalg.inv(H) @ np.stack([u.ravel(), v.ravel(), np.ones(u.size)])
    with np.errstate(divide="ignore", invalid="ignore"):
        x, y = np.where(p[2] > 0, p[0] / p[2], np.nan), np.where(p[2] > 0, p[1] / p[2], np.nan)
    return x.reshape(h, w), y.reshape(h, w)


def painting_region(H: np.ndarray, size: tuple[int, int], margin: float = REGION_MARGIN) -> np.ndarray:
    """``(H, W)`` bool: pixels of a view that see the painting's plane within its borders, the borders
    moved ``margin`` pixels inwards (in the view; see :func:`inverse_map` for ``H``)."""
    h, w = size
    x, y = inverse_map(H, size)
    with np.errstate(invalid="ignore"):
        region = (x >= -0.5) & (x <= w - 0.5) & (y >= -0.5) & (y <= h - 0.5)
    if margin > 0:
        region = ndimage.binary_erosion(region, iterations=int(np.ceil(margin)), border_value=0)
    return region


def warp_label(label: np.ndarray, H: np.ndarray) -> np.ndarray:
    """The label ``(H, W, 3)`` uint8 seen in a view through ``H`` (label -> view), bilinear;
    ``(H, W, 3)`` float64 0..255, NaN outside the label."""
    x, y = inverse_map(H, label.shape[:2])
    inside = np.isfinite(x)
    coords = np.stack([np.where(inside, y, -10.0), np.where(inside, x, -10.0)])
    return np.stack([ndimage.map_coordinates(label[..., c].astype(np.float64), coords, order=1, mode="constant",
                                             cval=np.nan) for c in range(3)], axis=-1)
