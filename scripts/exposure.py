"""Exposure of the paper's Blender renders against ours, one table.

Cuts the 6 renders and masks of each view out of the paper generator's contact sheets
(``--anchors``: 784 x 1474 pictures, cells of 256 x 192, see ``/work/shared/anchors/README.md``)
and renders ``--samples`` sequences of each ``--config`` preset at 384 x 512 with the sheets'
own source painting as texture (upscaled from the sheet), halved to 192 x 256 like the sheets'
cells. Statistics are those of :func:`sidar_torch.exposure.view_exposure` over painting pixels
(mask 0): the mean and median over views of the near-white (luma >= 250) and near-black
(luma <= 5) fractions, the median luma, and the luma histogram of all views pooled (8 bins).

    .venv/bin/python scripts/exposure.py --config misaligned paper_misaligned --samples 20
"""

from __future__ import annotations

import argparse
import glob

import numpy as np
from PIL import Image

from sidar_torch import load_config
from sidar_torch.dataset import render_sample
from sidar_torch.exposure import view_exposure
from sidar_torch.scene import sample_sequence


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
    texture = np.asarray(Image.fromarray(painting).resize((512, 384), Image.Resampling.BICUBIC))
    views, masks = [], []
    for i in range(samples):
        s = render_sample(sample_sequence(config, np.random.default_rng([0, i])), texture, config, i)
        views.append(halve(s["images"].permute(0, 2, 3, 1).numpy() * 255))
        masks.append(halve(s["masks"][:, 0].numpy()) >= 0.5)
    return np.concatenate(views).round().astype(np.uint8), np.concatenate(masks)


def row(name: str, views: np.ndarray, masks: np.ndarray) -> str:
    e = view_exposure(views, masks, bins=8)
    keep = e.painting > 0
    pooled = (e.histogram[keep] * e.painting[keep, None]).sum(0) / e.painting[keep].sum()
    return (f"| {name} | {keep.sum()} | {e.white[keep].mean():.3f} / {np.median(e.white[keep]):.3f} | "
            f"{e.black[keep].mean():.3f} / {np.median(e.black[keep]):.3f} | {np.median(e.median[keep]):.0f} | "
            + " ".join(f"{p:.2f}" for p in pooled) + " |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--anchors", default="/work/shared/anchors/blender-sidar-seed*.png")
    parser.add_argument("--config", nargs="+", default=["misaligned"])
    parser.add_argument("--samples", type=int, default=20)
    args = parser.parse_args()
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
