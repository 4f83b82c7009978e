"""Effective blur of a view against its painting: the Gaussian sigma (pixels) that best explains it.

A view ``j`` of a sequence shows the label (the painting in view 0's frame) through the known
homography ``H[j, 0]``, shaded by the scene's light and blurred by whatever the renderer's pixel
filter, texture sampling and camera effects do. :func:`view_blur` warps the label into the view,
blurs it (in linear light) with a Gaussian of each candidate sigma, fits the view's luminance on the
painting's unoccluded pixels as that blurred albedo times a quadratic light level in the pixel
coordinates (:data:`LEVEL_DEGREE`; the light varies slowly over the painting), and returns the sigma
of least residual, refined by a parabola through the best grid point and its neighbours.

    python -m benchmarks.blur --anchors DIR --config paper_misaligned
    python -m benchmarks.blur --anchors DIR --config misaligned --post-sigma 0.5

prints view 0's blur for each anchor sequence (the paper generator's Cycles views, against the
source painting) and for one sequence of ours per anchor with the same painting; ``--post-sigma``
blurs our views by a known Gaussian first (the measure must recover it).
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np
import torch
from scipy import ndimage

from benchmarks.common import parse_set
from benchmarks.realism import (anchor_sequences, luminance, painting_region, read_rgb, srgb_to_linear, to_uint8,
                                warp_label)
from sidar_torch.effects import linear_to_srgb

SIGMAS = np.round(np.arange(0.0, 2.51, 0.1), 2)
"""Candidate Gaussian sigmas (pixels) of the grid search."""

TILE = 24
"""Side (pixels) of the square tiles in each of which the light is taken as an affine function of the
albedo (gain and offset: the light level, a specular wash or ambient light varies slowly)."""

EDGE_MARGIN = 4
"""Pixels nearer than this to an occluder, a blown-out pixel, the painting's border or the image's
border are not judged (their neighbourhood holds something other than the lit painting)."""

BLOWN = 250
"""A view pixel with a channel at or above this 8-bit value is clipped: not judged."""

MIN_TILE = TILE * TILE // 2
"""Judged pixels a tile needs to count."""

MIN_PIXELS = 2000
"""Fewer judged pixels (in counted tiles) than this: no figure (NaN)."""


def gaussian(image: np.ndarray, sigma: float) -> np.ndarray:
    """``(H, W)`` float64 blurred by a separable Gaussian of ``sigma`` pixels (identity at 0)."""
    return image if sigma <= 0 else ndimage.gaussian_filter(image, sigma, mode="nearest", truncate=4.0)


def blur_residuals(view: np.ndarray, mask: np.ndarray, label: np.ndarray, H: np.ndarray,
                   sigmas: np.ndarray | None = None) -> np.ndarray:
    """Mean squared residual ``(len(sigmas),)`` of the view's luminance explained, tile by tile, as an
    affine function of the label warped into the view and blurred by each sigma (NaN: too few pixels).

    Args:
        view: ``(H, W, 3)`` uint8 sRGB view.
        mask: ``(H, W)`` bool, True where the painting is not visible.
        label: ``(H, W, 3)`` uint8 sRGB, the painting in view 0's frame (or the source painting when
            it fills view 0's frame).
        H: ``(3, 3)`` homography label -> view (Kornia convention, see ``realism.inverse_map``).
    """
    sigmas = SIGMAS if sigmas is None else sigmas
    if view.shape != label.shape or mask.shape != view.shape[:2] or view.ndim != 3:
        raise ValueError(f"view {view.shape}, mask {mask.shape} and label {label.shape} must share (H, W)")
    albedo_srgb = warp_label(label, H)
    inside = np.isfinite(albedo_srgb).all(-1)
    albedo = luminance(np.nan_to_num(albedo_srgb).round().clip(0, 255).astype(np.uint8))
    clipped = (view >= BLOWN).any(-1)
    judged = ndimage.binary_erosion(~mask & inside & ~clipped & painting_region(H, view.shape[:2], 0),
                                    iterations=EDGE_MARGIN, border_value=0)
    h, w = view.shape[:2]
    ys, xs = np.nonzero(judged)
    tiles = (ys // TILE) * (w // TILE + 1) + xs // TILE
    counts = np.bincount(tiles)
    keep = counts[tiles] >= MIN_TILE
    if keep.sum() < MIN_PIXELS:
        return np.full(len(sigmas), np.nan)
    tiles = np.unique(tiles[keep], return_inverse=True)[1]
    n = np.bincount(tiles).astype(np.float64)
    target = luminance(view)[ys[keep], xs[keep]]
    t_mean = np.bincount(tiles, target) / n
    t_c = target - t_mean[tiles]
    out = []
    for sigma in sigmas:
        x = gaussian(albedo, float(sigma))[ys[keep], xs[keep]]
        x_c = x - (np.bincount(tiles, x) / n)[tiles]
        sxx, sxy = np.bincount(tiles, x_c * x_c), np.bincount(tiles, x_c * t_c)
        syy = np.bincount(tiles, t_c * t_c)
        with np.errstate(divide="ignore", invalid="ignore"):
            residual = np.where(sxx > 0, syy - sxy**2 / sxx, syy)
        out.append(residual.sum() / len(target))
    return np.array(out)


def view_blur(view: np.ndarray, mask: np.ndarray, label: np.ndarray, H: np.ndarray) -> float:
    """Effective Gaussian blur of one view, in pixels: the sigma of least :func:`blur_residuals`,
    refined by a parabola through it and its grid neighbours (NaN when too few pixels are judged).
    Arguments as :func:`blur_residuals`."""
    r = blur_residuals(view, mask, label, H)
    if not np.isfinite(r).all():
        return float("nan")
    best = int(np.argmin(r))
    if 0 < best < len(r) - 1:
        curve = r[best - 1] - 2 * r[best] + r[best + 1]
        if curve > 0:
            return float(SIGMAS[best] + (SIGMAS[1] - SIGMAS[0]) * 0.5 * (r[best - 1] - r[best + 1]) / curve)
    return float(SIGMAS[best])


def anchor_view0_blur(sequence: Path) -> float:
    """View 0's blur of one of the paper generator's sequences: ``0.png`` against ``source.png`` (the
    painting fills view 0's frame exactly there; ``gt.png`` is itself a render, blurred)."""
    view = read_rgb(sequence / "0.png")
    mask = read_rgb(sequence / "0-m.png")[..., 0] >= 128
    return view_blur(view, mask, read_rgb(sequence / "source.png"), np.eye(3))


def blur_linear(view: np.ndarray, sigma: float) -> np.ndarray:
    """``(H, W, 3)`` uint8 sRGB blurred by a Gaussian of ``sigma`` pixels in linear light, re-encoded."""
    return encode(np.stack([gaussian(c, sigma) for c in np.moveaxis(srgb_to_linear(view), -1, 0)], axis=-1))


def encode(linear: np.ndarray) -> np.ndarray:
    """Linear light ``(..., 3)`` float in [0, 1] (clipped) to 8-bit sRGB ``(..., 3)`` uint8 (exact curve)."""
    srgb = linear_to_srgb(torch.from_numpy(np.clip(np.asarray(linear, np.float64), 0, 1))).numpy()
    return (255 * srgb).round().astype(np.uint8)


def our_view0_blurs(config: Any, sources: list[Path], samples: int, seed: int,
                    post_sigma: float = 0.0) -> np.ndarray:
    """View 0's blur ``(samples,)`` of ``samples`` sequences of ``config`` with ``sources`` as the
    paintings (painting ``index % len``), against the exact label; ``post_sigma`` > 0 first blurs
    each view by that Gaussian (:func:`blur_linear`), to check that the measure recovers it."""
    from sidar_torch import SidarDataset
    from sidar_torch.sample import render_sample
    from sidar_torch.scene import sample_sequence

    dataset = SidarDataset(source=[str(p) for p in sources], config=config, seed=seed)
    out = []
    for index in range(samples):
        rng = dataset.generator(index)
        scene = sample_sequence(dataset.config, rng)
        painting = dataset.source.painting(index % len(dataset.source), dataset.config.image_size)
        sample = render_sample(scene, painting, dataset.config, index, rng=rng)
        view = to_uint8(sample["images"][:1])[0]
        if post_sigma > 0:
            view = blur_linear(view, post_sigma)
        label = to_uint8(sample["label"][None])[0]
        H = sample["homographies"][0, 0].double().numpy()
        out.append(view_blur(view, sample["masks"][0, 0].numpy() > 0.5, label, H))
    return np.array(out)


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``python -m benchmarks.blur``; parsing it runs nothing."""
    parser = argparse.ArgumentParser(prog="python -m benchmarks.blur", description=__doc__.splitlines()[0])
    parser.add_argument("--anchors", type=Path, required=True, help="folder of the paper's sequences")
    parser.add_argument("--config", default="paper_misaligned", help="our preset rendered with the same paintings")
    parser.add_argument("--set", nargs="*", default=[], metavar="KEY=VALUE", help="config overrides (values as YAML)")
    parser.add_argument("--post-sigma", type=float, default=0.0, help="blur our views by this first (a check)")
    parser.add_argument("--seed", type=int, default=0)
    return parser


def main(argv: list[str] | None = None) -> None:
    from sidar_torch import load_config

    args = build_parser().parse_args(argv)
    sequences = anchor_sequences(args.anchors)
    theirs = np.array([anchor_view0_blur(s) for s in sequences])
    size = read_rgb(sequences[0] / "source.png").shape[:2]
    config = load_config(args.config, image_size=size, **parse_set(args.set))
    ours = our_view0_blurs(config, [s / "source.png" for s in sequences], len(sequences), args.seed,
                           args.post_sigma)
    print(f"| sequence | Blender view 0 blur (px) | {args.config} view 0 blur (px) |")
    print("|---|---|---|")
    for s, a, b in zip(sequences, theirs, ours):
        print(f"| {s.name} | {a:.2f} | {b:.2f} |")
    print(f"| median | {np.nanmedian(theirs):.2f} | {np.nanmedian(ours):.2f} |")


if __name__ == "__main__":
    main()
