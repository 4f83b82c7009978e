"""A figure of the shadow outputs: for a few samples, the view, its shadow mask and its shadow-free view.

Takes the first ``--samples`` samples of ``--config`` (seed 0, 192x256) whose view 1 has at least
``--min-shadow`` pixels with a shadow mask of 0.5 or more, and writes a grid: one row per sample,
columns view | shadow mask (white = all the direct light blocked) | shadow-free view.

    .venv/bin/python scripts/shadow_figure.py --out docs/shadow_masks.jpg
"""

from __future__ import annotations

import argparse

import torch
from PIL import Image

from sidar_torch import SidarDataset, load_config


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", default="misaligned", help="preset name or YAML path")
    parser.add_argument("--samples", type=int, default=3, help="samples shown (rows)")
    parser.add_argument("--min-shadow", type=int, default=1000, help="half-shadowed pixels a sample's view 1 needs")
    parser.add_argument("--out", default="docs/shadow_masks.jpg")
    args = parser.parse_args(argv)
    config = load_config(args.config, image_size=(192, 256), n_views=2, shadow_mask_output=True,
                         shadow_free_output=True)
    dataset = SidarDataset(config=config, seed=0)
    rows, index = [], 0
    while len(rows) < args.samples:
        if index == 1000:
            raise SystemExit(f"fewer than {args.samples} of the first 1000 samples have {args.min_shadow} shadowed pixels")
        sample = dataset.sample(index)
        if (sample["shadow_masks"][1] >= 0.5).sum() >= args.min_shadow:
            rows.append(torch.cat([sample["images"][1], sample["shadow_masks"][1].expand(3, -1, -1),
                                   sample["shadow_free"][1]], dim=2))  # (3, H, 3 W)
        index += 1
    pixels = torch.cat(rows, dim=1).mul(255).round().byte().permute(1, 2, 0).numpy()
    Image.fromarray(pixels).save(args.out, quality=90)
    print(f"{args.out}: {args.samples} samples of {args.config} (seed 0) among the first {index}")


if __name__ == "__main__":
    main()
