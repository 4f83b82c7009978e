"""A figure of the soft opacities: for a few views, the view, its mask and its opacities side by side.

Picks the first sample of ``--config`` (seed 0) with at least ``--min-soft`` pixels of partial
opacity, and writes a PNG grid: one row per view, columns view | masks | opacities (white = 1).

    .venv/bin/python scripts/opacity_figure.py --out docs/opacity.png
"""

from __future__ import annotations

import argparse

import torch
from PIL import Image

from sidar_torch import SidarDataset, load_config


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", default="misaligned", help="preset name or YAML path")
    parser.add_argument("--size", type=int, nargs=2, default=(192, 256), metavar=("H", "W"))
    parser.add_argument("--views", type=int, default=3, help="views shown (rows)")
    parser.add_argument("--min-soft", type=int, default=2000, help="partially hidden pixels the sample needs")
    parser.add_argument("--out", default="docs/opacity.png")
    args = parser.parse_args()
    config = load_config(args.config, image_size=tuple(args.size), n_views=args.views, opacity_output=True)
    dataset = SidarDataset(config=config, seed=0)
    for index in range(1000):
        sample = dataset.sample(index)
        soft = ((sample["opacities"] > 0) & (sample["opacities"] < 1)).sum()
        if soft >= args.min_soft:
            break
    else:
        raise SystemExit(f"no sample among the first 1000 has {args.min_soft} partially hidden pixels")
    columns = [sample["images"], sample["masks"].expand(-1, 3, -1, -1), sample["opacities"].expand(-1, 3, -1, -1)]
    grid = torch.cat([torch.cat(list(column), dim=1) for column in columns], dim=2)  # (3, V H, 3 W)
    pixels = grid.mul(255).round().byte().permute(1, 2, 0).numpy()
    Image.fromarray(pixels).save(args.out)
    print(f"{args.out}: sample {index} of {args.config} (seed 0), {int(soft)} partially hidden pixels")


if __name__ == "__main__":
    main()
