"""Exposure statistics of rendered views: how much of the visible painting is blown out or black.

Used to calibrate the light and ambient ranges against the paper's Blender renders
(``scripts/exposure.py`` measures both). Only *painting* pixels count (mask 0): the black
background and the occluders would otherwise dominate the dark end.

Luminance is Rec. 709 luma of the 8-bit sRGB values, ``0.2126 R + 0.7152 G + 0.0722 B``, in
0..255; a pixel is *near-white* at luma >= :data:`WHITE` and *near-black* at luma <= :data:`BLACK`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["BLACK", "WHITE", "ViewExposure", "view_exposure"]

WHITE = 250
"""Luma (0..255) from which a painting pixel counts as near-white (blown out)."""

BLACK = 5
"""Luma (0..255) up to which a painting pixel counts as near-black."""

LUMA = np.array([0.2126, 0.7152, 0.0722])
"""Rec. 709 luma weights for R, G, B."""


@dataclass(frozen=True)
class ViewExposure:
    """Exposure of the painting pixels of ``V`` views.

    Attributes:
        white: ``(V,)`` fraction of painting pixels with luma >= :data:`WHITE`.
        black: ``(V,)`` fraction of painting pixels with luma <= :data:`BLACK`.
        median: ``(V,)`` median luma of the painting pixels.
        histogram: ``(V, bins)`` luma histogram of the painting pixels over 0..256, each row summing
            to 1.
        painting: ``(V,)`` number of painting pixels; a view with none has NaN statistics.
    """

    white: np.ndarray
    black: np.ndarray
    median: np.ndarray
    histogram: np.ndarray
    painting: np.ndarray


def view_exposure(views: np.ndarray, masks: np.ndarray, bins: int = 16) -> ViewExposure:
    """Exposure statistics of each view's painting pixels.

    Args:
        views: ``(V, H, W, 3)`` uint8 sRGB.
        masks: ``(V, H, W)`` bool, True where the painting is not visible (ignored pixels).
        bins: number of equal luma bins over 0..256 in the histogram.
    """
    views, masks = np.asarray(views), np.asarray(masks, bool)
    if views.ndim != 4 or views.shape[-1] != 3 or views.dtype != np.uint8:
        raise ValueError(f"views: expected (V, H, W, 3) uint8, got {views.shape} {views.dtype}")
    if masks.shape != views.shape[:3]:
        raise ValueError(f"masks: expected shape {views.shape[:3]}, got {masks.shape}")
    rows = []
    for view, mask in zip(views, masks):
        luma = (view.astype(np.float64) @ LUMA)[~mask]
        if luma.size == 0:
            rows.append((np.nan, np.nan, np.nan, np.full(bins, np.nan), 0))
            continue
        histogram = np.histogram(luma, bins=bins, range=(0, 256))[0] / luma.size
        rows.append(((luma >= WHITE).mean(), (luma <= BLACK).mean(), np.median(luma), histogram, luma.size))
    white, black, median, histogram, painting = zip(*rows)
    return ViewExposure(np.array(white), np.array(black), np.array(median), np.stack(histogram), np.array(painting))

