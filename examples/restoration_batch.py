"""A restoration / inpainting batch: aligned views and their masks in, the artifact-free label out.

    python examples/restoration_batch.py [--quick]

The ``aligned`` preset renders every view through the reference camera (all homographies are the
identity), so the views show the painting at the same pixels under different lights, shadows and
occluders; the paper's restoration task maps the stack of views (and, for inpainting, the masks)
to the label. This builds such a batch from a DataLoader, prints its shapes and, as sanity
figures, the PSNR against the label of three estimators that need no training: view 0 alone,
the mean of the views, and the per-pixel median of the views that see the painting there (by
the masks), and the fraction of pixels no view sees (no method can recover those from the views).
"""

from __future__ import annotations

import argparse

import torch
from torch.utils.data import DataLoader

from sidar_torch import SidarDataset, load_config


def psnr(estimate: torch.Tensor, label: torch.Tensor, where: torch.Tensor) -> float:
    """PSNR in dB of ``estimate`` against ``label``, both ``(B, 3, H, W)`` in [0, 1], over the pixels
    ``where`` ``(B, 1, H, W)`` is true."""
    where = where.expand_as(label)
    mse = (estimate - label)[where].square().mean()
    return (10 * torch.log10(1 / mse)).item()


def main(argv: list[str] | None = None) -> dict[str, float]:
    """Build one batch, print its shapes and the baselines' PSNR; returns ``{estimator: PSNR}``."""
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="2 small samples of 3 views, rendered in this process")
    quick = parser.parse_args(argv).quick
    config = load_config("aligned", image_size=(48, 64) if quick else (192, 256), n_views=3 if quick else 6)
    loader = DataLoader(SidarDataset(config=config, seed=0), batch_size=2 if quick else 8,
                        num_workers=0 if quick else 2)
    batch = next(iter(loader))
    # (B, V, 3, H, W), (B, V, 1, H, W), (B, 3, H, W)
    images, masks, label = batch["images"], batch["masks"], batch["label"]

    network_input = torch.cat([images, masks], 2).flatten(1, 2)  # (B, 4V, H, W): every view's RGB and its mask
    print(f"images {tuple(images.shape)}, masks {tuple(masks.shape)}, label {tuple(label.shape)}")
    print(f"network input (views and masks stacked) {tuple(network_input.shape)} -> target {tuple(label.shape)}")
    identity = torch.eye(3).expand_as(batch["homographies"])
    print(f"aligned preset: largest |H - I| {(batch['homographies'] - identity).abs().max().item():.1e}")

    visible = masks == 0  # (B, V, 1, H, W)
    seen = visible.any(1)  # (B, 1, H, W): some view sees the painting there
    median = images.masked_fill(~visible, float("nan")).nanmedian(1).values.nan_to_num(0.0)
    estimates = {
        "view 0": images[:, 0],
        "mean of the views": images.mean(1),
        "median of the visible views": median,
    }
    everywhere = torch.ones_like(seen)
    print(f"pixels no view sees: {1 - seen.float().mean().item():.2%}")
    print("\n| estimator | PSNR, all pixels (dB) | PSNR, pixels some view sees (dB) |\n|---|---|---|")
    results = {}
    for name, estimate in estimates.items():
        results[name] = psnr(estimate, label, seen)
        print(f"| {name} | {psnr(estimate, label, everywhere):.2f} | {results[name]:.2f} |")
    return results


if __name__ == "__main__":
    main()
