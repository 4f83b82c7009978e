"""A figure of the lens models: a grid painting seen through each model, evenly lit, no occluders.

One column per lens (none, Brown-Conrady barrel, Brown-Conrady pincushion, division barrel; each
coefficient fixed at the image's corner), one row per view of the same scene (seed 0, index 0): view 0,
the fronto-parallel reference, then a tilted view. Writes a PNG grid.

    .venv/bin/python scripts/lens_figure.py --out docs/lens.png
"""

from __future__ import annotations

import argparse

import numpy as np
import torch
from PIL import Image

from sidar_torch import SidarDataset, load_config

LENSES = {
    "none": dict(lens_model="none"),
    "brown_conrady, k1 = -0.1": dict(lens_model="brown_conrady", lens_k1=(-0.1, -0.1), lens_k2=(0, 0),
                                      lens_p1=(0, 0), lens_p2=(0, 0)),
    "brown_conrady, k1 = +0.1": dict(lens_model="brown_conrady", lens_k1=(0.1, 0.1), lens_k2=(0, 0),
                                      lens_p1=(0, 0), lens_p2=(0, 0)),
    "division, lambda = -0.2": dict(lens_model="division", lens_lambda=(-0.2, -0.2)),
}
"""Column title -> config overrides (coefficients at the image's corner, ``docs/lens.md``)."""


def grid_painting(size: tuple[int, int], step: int = 16) -> np.ndarray:
    """``(H, W, 3)`` uint8: black lines every ``step`` pixels on white, a red border."""
    h, w = size
    painting = np.full((h, w, 3), 255, np.uint8)
    painting[::step] = painting[:, ::step] = 0
    painting[:3], painting[-3:], painting[:, :3], painting[:, -3:] = [(220, 30, 30)] * 4
    return painting


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, nargs=2, default=(192, 256), metavar=("H", "W"))
    parser.add_argument("--out", default="docs/lens.png")
    args = parser.parse_args()
    size = tuple(args.size)
    base = load_config("misaligned", image_size=size, n_views=2, n_lights=(0, 0), ambient=(1.0, 1.0),
                       n_occluders=(0, 0), plane_diffuse=True)
    columns = []
    for overrides in LENSES.values():
        sample = SidarDataset([grid_painting(size)], base.replace(**overrides), seed=0).sample(0)
        columns.append(torch.cat(list(sample["images"]), dim=1))  # (3, V H, W)
    white = torch.ones(3, columns[0].shape[1], 8)
    grid = torch.cat([part for column in columns for part in (column, white)][:-1], dim=2)
    Image.fromarray(grid.mul(255).round().byte().permute(1, 2, 0).numpy()).save(args.out)
    print(f"{args.out}: columns {', '.join(LENSES)}; rows view 0, view 1 (misaligned, seed 0, index 0)")


if __name__ == "__main__":
    main()
