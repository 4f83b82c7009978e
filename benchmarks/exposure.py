"""Exposure of the paper's Blender renders against ours: how much of the visible painting is blown
out or black. ``python -m benchmarks.exposure --anchors 'DIR/*.png' [--config PRESET ...]``.

Used to calibrate the light and ambient ranges against the paper's Blender renders. Only
*painting* pixels count (mask 0): the black background and the occluders would otherwise
dominate the dark end.

``--anchors`` is a glob of contact sheets the paper's generator made (784 x 1474 pictures: the
source painting at the top, then per view a row with the 256 x 192 render and its grey-level
mask, see :func:`anchor_sheet`). The command cuts the 6 renders and masks of each view out of
them, renders ``--samples`` sequences of each ``--config`` preset at 384 x 512 (H x W) with the
sheets' own source painting as texture (upscaled from the sheet), halved to 192 x 256 like the
sheets' cells, and prints one table row per set: the mean and median over views of the
near-white and near-black fractions, the median luma, and the luma histogram of all views
pooled (8 bins).

Luminance is Rec. 709 luma of the 8-bit sRGB values, ``0.2126 R + 0.7152 G + 0.0722 B``, in
0..255; a pixel is *near-white* at luma >= :data:`WHITE` and *near-black* at luma <= :data:`BLACK`.
"""

from __future__ import annotations

import argparse
import glob
from dataclasses import dataclass

import numpy as np
from PIL import Image

import torch

from sidar_torch import SidarDataset, load_config

from .common import DEFAULT_PRESET

__all__ = ["BLACK", "LUMA", "WHITE", "ViewExposure", "anchor_sheet", "build_parser", "main", "view_exposure"]

WHITE = 250
"""Luma (0..255) from which a painting pixel counts as near-white (blown out)."""

BLACK = 5
"""Luma (0..255) up to which a painting pixel counts as near-black."""

LUMA = np.array([0.2126, 0.7152, 0.0722])
"""Rec. 709 luma weights for R, G, B."""

CLIPPED, STILL_COLOURED, MIN_CLIPPED = 254, 200, 100
"""A painting pixel is *clipped* when a channel is at least ``CLIPPED``, and a clipped one is still
coloured when another channel is below ``STILL_COLOURED`` (an over-exposure clipped per channel, as
Blender's Standard view transform does, where a spill into white would have whitened it); a view
needs ``MIN_CLIPPED`` clipped pixels for a figure."""


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
        clipped_coloured: ``(V,)`` fraction of the clipped painting pixels that are still coloured
            (:data:`CLIPPED`; NaN with fewer than :data:`MIN_CLIPPED` clipped pixels).
    """

    white: np.ndarray
    black: np.ndarray
    median: np.ndarray
    histogram: np.ndarray
    painting: np.ndarray
    clipped_coloured: np.ndarray


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
        pixels = view[~mask]
        luma = pixels.astype(np.float64) @ LUMA
        if luma.size == 0:
            rows.append((np.nan, np.nan, np.nan, np.full(bins, np.nan), 0, np.nan))
            continue
        histogram = np.histogram(luma, bins=bins, range=(0, 256))[0] / luma.size
        clipped = pixels.max(axis=1) >= CLIPPED
        coloured = (pixels[clipped].min(axis=1) < STILL_COLOURED).mean() if clipped.sum() >= MIN_CLIPPED else np.nan
        rows.append(((luma >= WHITE).mean(), (luma <= BLACK).mean(), np.median(luma), histogram, luma.size, coloured))
    white, black, median, histogram, painting, coloured = zip(*rows)
    return ViewExposure(np.array(white), np.array(black), np.array(median), np.stack(histogram), np.array(painting),
                        np.array(coloured))


def anchor_sheet(path: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Renders ``(6, 192, 256, 3)`` uint8, masks ``(6, 192, 256)`` bool (True: not painting; the
    sheet's grey-level masks thresholded at 128) and the source painting ``(192, 256, 3)`` of a sheet."""
    sheet = np.asarray(Image.open(path).convert("RGB"))
    if sheet.shape != (1474, 784, 3):
        raise SystemExit(f"{path}: expected a 784 x 1474 contact sheet, got {sheet.shape[1]} x {sheet.shape[0]}")
    top = [226 + 210 * v for v in range(6)]  # first pixel row of each view's cells
    renders = np.stack([sheet[y:y + 192, 4:260] for y in top])
    masks = np.stack([sheet[y:y + 192, 264:520].mean(axis=2) >= 128 for y in top])
    return renders, masks, sheet[16:208, 264:520].copy()


def halve(images: np.ndarray) -> np.ndarray:
    """2 x 2 box average of ``(..., H, W[, C])`` arrays, as the sheets' cells are."""
    h, w = images.shape[-3:-1] if images.ndim == 4 else images.shape[-2:]
    shape = (*images.shape[:-3], h // 2, 2, w // 2, 2, 3) if images.ndim == 4 else (*images.shape[:-2], h // 2, 2, w // 2, 2)
    return images.reshape(shape).mean(axis=(-4, -2) if images.ndim == 4 else (-3, -1))


def ours(preset: str, painting: np.ndarray, samples: int) -> tuple[np.ndarray, np.ndarray]:
    """Views ``(N, 192, 256, 3)`` uint8 and masks of ``samples`` sequences of ``preset`` (seeds 0..)."""
    config = load_config(preset, image_size=(384, 512))
    texture = np.array(Image.fromarray(painting).resize((512, 384), Image.Resampling.BICUBIC))
    dataset = SidarDataset(source=torch.from_numpy(texture).permute(2, 0, 1)[None], config=config, seed=0)
    views, masks = [], []
    for i in range(samples):
        s = dataset.sample(i)
        views.append(halve(s["images"].permute(0, 2, 3, 1).numpy() * 255))
        masks.append(halve(s["masks"][:, 0].numpy()) >= 0.5)
    return np.concatenate(views).round().astype(np.uint8), np.concatenate(masks)


def row(name: str, views: np.ndarray, masks: np.ndarray) -> str:
    """One table row: exposure statistics of ``views`` (see the module docstring)."""
    e = view_exposure(views, masks, bins=8)
    keep = e.painting > 0
    pooled = (e.histogram[keep] * e.painting[keep, None]).sum(0) / e.painting[keep].sum()
    return (f"| {name} | {keep.sum()} | {e.white[keep].mean():.3f} / {np.median(e.white[keep]):.3f} | "
            f"{e.black[keep].mean():.3f} / {np.median(e.black[keep]):.3f} | {np.median(e.median[keep]):.0f} | "
            + " ".join(f"{p:.2f}" for p in pooled) + " |")


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``python -m benchmarks.exposure``; parsing it runs nothing."""
    parser = argparse.ArgumentParser(prog="python -m benchmarks.exposure", description=__doc__.split("\n\n")[0])
    parser.add_argument("--anchors", required=True, metavar="GLOB",
                        help="glob of the paper generator's contact sheets (784 x 1474 PNGs), quoted")
    parser.add_argument("--config", nargs="+", default=[DEFAULT_PRESET], help="presets or YAML paths to compare")
    parser.add_argument("--samples", type=int, default=20, help="sequences rendered per preset (default 20)")
    return parser


def main(argv: list[str] | None = None) -> None:
    args = build_parser().parse_args(argv)
    sheets = [anchor_sheet(p) for p in sorted(glob.glob(args.anchors))]
    if not sheets:
        raise SystemExit(f"--anchors {args.anchors!r}: no contact sheet found")
    print("| renders | views | near-white mean / median | near-black mean / median | median luma | "
          "luma histogram (8 bins, pooled) |")
    print("|---|---|---|---|---|---|")
    print(row("paper (Blender/Cycles)", np.concatenate([s[0] for s in sheets]), np.concatenate([s[1] for s in sheets])))
    for preset in args.config:
        print(row(f"ours: {preset}", *ours(preset, sheets[0][2], args.samples)), flush=True)


if __name__ == "__main__":
    main()
