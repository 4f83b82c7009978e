"""Effective blur of a view against its painting: the Gaussian sigma (pixels) that best explains it.

A view ``j`` of a sequence shows the painting through the known homography ``H[j, 0]``, shaded by the
scene's light and blurred by whatever the renderer's pixel filter, texture sampling and camera effects
do. :func:`view_blur` warps the painting into the view, blurs it (in linear light) with a Gaussian of
each candidate sigma, takes the high frequencies of both (each image less its Gaussian blur of
:data:`HIGH_PASS` px: the light, highlights and specular washes vary slowly and are left out), fits the
view's as a gain times the painting's in each :data:`TILE`-pixel tile (with an offset), and returns
the sigma of least residual, refined by a parabola through the best grid point and its neighbours.

The painting is the sharp one: our exact label, or the paper's ``source.png`` (which fills its view 0
exactly), never the paper's ``gt.png``, an EEVEE render that is itself blurred (0.75 px against its
source): against it a view reads sharper than it is (``--against label``).

    python -m benchmarks.blur --anchors DIR --config paper_misaligned
    python -m benchmarks.blur --anchors DIR --config paper_misaligned --set pixel_filter_sigma=0 --post-sigma 0.8

prints view 0's blur for each anchor sequence (the paper generator's Cycles views, against the
source painting) and for ``--samples`` sequences of ours with the same paintings; ``--post-sigma``
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
from benchmarks.images import (anchor_sequences, luminance, painting_region, read_rgb, srgb_to_linear, to_uint8,
                               warp_label)
from sidar_torch.sample.effects import linear_to_srgb

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

HIGH_PASS = 2.0
"""Sigma (pixels) of the Gaussian whose blur is subtracted from the view and from the blurred painting
before the fit: what is left is the painting's texture at the scales a blur of 0-2.5 px changes. Without
it, shading that varies within a tile (a highlight, a spot's edge) on a painting of faint texture is
best explained by a wide blur, whose low frequencies follow it by chance (the paper's retina and
chelsea views read 1.4 px, 0.55 and 0.64 px with it; ``tests/benchmarks/test_blur.py``)."""

MIN_TILE = TILE * TILE // 2
"""Judged pixels a tile needs to count."""

MIN_PIXELS = 2000
"""Fewer judged pixels (in counted tiles) than this: no figure (NaN)."""


def gaussian(image: np.ndarray, sigma: float) -> np.ndarray:
    """``(H, W)`` float64 blurred by a separable Gaussian of ``sigma`` pixels (identity at 0)."""
    return image if sigma <= 0 else ndimage.gaussian_filter(image, sigma, mode="nearest", truncate=4.0)


def high_pass(image: np.ndarray) -> np.ndarray:
    """``(H, W)`` float64 less its Gaussian blur of :data:`HIGH_PASS` pixels."""
    return image - gaussian(image, HIGH_PASS)


def blur_residuals(view: np.ndarray, mask: np.ndarray, label: np.ndarray, H: np.ndarray,
                   sigmas: np.ndarray | None = None) -> np.ndarray:
    """Mean squared residual ``(len(sigmas),)`` of the view's luminance explained, tile by tile, as an
    affine function of the label warped into the view and blurred by each sigma, both high-passed
    (:func:`high_pass`; NaN: too few pixels).

    Args:
        view: ``(H, W, 3)`` uint8 sRGB view.
        mask: ``(H, W)`` bool, True where the painting is not visible.
        label: ``(H, W, 3)`` uint8 sRGB, the painting in view 0's frame (or the source painting when
            it fills view 0's frame).
        H: ``(3, 3)`` homography label -> view (Kornia convention, see ``images.inverse_map``).
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
    target = high_pass(luminance(view))[ys[keep], xs[keep]]
    t_mean = np.bincount(tiles, target) / n
    t_c = target - t_mean[tiles]
    out = []
    for sigma in sigmas:
        x = high_pass(gaussian(albedo, float(sigma)))[ys[keep], xs[keep]]
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


ANCHOR_PAINTINGS = {"source": "source.png", "label": "gt.png"}
"""What an anchor's view 0 can be measured against: the painting itself (the measure), or the paper's
label, itself blurred by its EEVEE render (to show how much that hides)."""


def anchor_view0_blur(sequence: Path, against: str = "source") -> float:
    """View 0's blur of one of the paper generator's sequences: ``0.png`` against ``source.png`` (the
    painting fills view 0's frame exactly there), or against ``gt.png`` with ``against="label"``."""
    if against not in ANCHOR_PAINTINGS:
        raise ValueError(f"against={against!r}: expected one of {sorted(ANCHOR_PAINTINGS)}")
    view = read_rgb(sequence / "0.png")
    mask = read_rgb(sequence / "0-m.png")[..., 0] >= 128
    return view_blur(view, mask, read_rgb(sequence / ANCHOR_PAINTINGS[against]), np.eye(3))


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
        sample = render_sample(dataset.renderer(), scene, painting, dataset.config, index, rng=rng)
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
    parser.add_argument("--against", choices=sorted(ANCHOR_PAINTINGS), default="source",
                        help="measure the paper's views against its source painting or its (blurred) label")
    parser.add_argument("--samples", type=int, default=0, help="our sequences (default: one per anchor)")
    parser.add_argument("--seed", type=int, default=0)
    return parser


def main(argv: list[str] | None = None) -> None:
    from sidar_torch import load_config

    args = build_parser().parse_args(argv)
    sequences = anchor_sequences(args.anchors)
    theirs = np.array([anchor_view0_blur(s, args.against) for s in sequences])
    size = read_rgb(sequences[0] / "source.png").shape[:2]
    config = load_config(args.config, image_size=size, **parse_set(args.set))
    samples = args.samples or len(sequences)
    ours = our_view0_blurs(config, [s / "source.png" for s in sequences], samples, args.seed, args.post_sigma)
    print(f"| sequence | Blender view 0 blur (px, against {args.against}) | {args.config} view 0 blur (px) |")
    print("|---|---|---|")
    for k in range(max(len(sequences), samples)):
        a = f"{theirs[k]:.2f}" if k < len(sequences) else ""
        b = f"{ours[k]:.2f}" if k < samples else ""
        print(f"| {k} | {a} | {b} |")
    print(f"| median | {np.nanmedian(theirs):.2f} | {np.nanmedian(ours):.2f} |")


if __name__ == "__main__":
    main()
