"""A figure of the ``parallax`` preset: views of one static scene, their depth, the flow to another
view, where it is valid, and that view read along the flow.

Rows are views 1..V-1 of the first sample of ``--config`` (seed 0); columns: the view | its depth
(near white, far dark, nothing black) | its flow to view 0 (hue: direction, brightness: length) |
where the flow is valid (white) | view 0 read along the flow where it is valid (grey elsewhere),
which matches the view on occluders as well as on the painting.

    .venv/bin/python scripts/parallax_figure.py --out docs/parallax.jpg
"""

from __future__ import annotations

import argparse
import math

import kornia
import torch
import torch.nn.functional as F
from PIL import Image

from sidar_torch import SidarDataset, flow, load_config


def flow_colours(flows: torch.Tensor, valid: torch.Tensor, longest: float) -> torch.Tensor:
    """``(3, H, W)`` RGB in [0, 1] of ``flows`` ``(2, H, W)``: hue its direction, value its length over
    ``longest``; black where not ``valid`` ``(1, H, W)``."""
    hue = torch.atan2(flows[1], flows[0]) % (2 * math.pi)
    value = (flows.norm(dim=0) / longest).clamp(0, 1)
    hsv = torch.stack([hue, torch.ones_like(hue), value])
    return torch.where(valid, kornia.color.hsv_to_rgb(hsv.nan_to_num(0.0)), torch.zeros(3, 1, 1))


def read_along(image: torch.Tensor, flows: torch.Tensor, valid: torch.Tensor) -> torch.Tensor:
    """``image`` ``(3, H, W)`` read (bilinear) at every pixel plus ``flows``; mid grey where not ``valid``."""
    _, H, W = image.shape
    v, u = torch.meshgrid(torch.arange(H, dtype=torch.float32), torch.arange(W, dtype=torch.float32), indexing="ij")
    x, y = (u + flows[0]).nan_to_num(-2.0), (v + flows[1]).nan_to_num(-2.0)
    grid = torch.stack([2 * x / (W - 1) - 1, 2 * y / (H - 1) - 1], -1)[None]
    read = F.grid_sample(image[None], grid, mode="bilinear", align_corners=True)[0]
    return torch.where(valid, read, torch.full_like(read, 0.5))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", default="parallax", help="preset name or YAML path (with depth_output)")
    parser.add_argument("--size", type=int, nargs=2, default=(192, 256), metavar=("H", "W"))
    parser.add_argument("--views", type=int, default=4, help="views rendered (rows: all but view 0)")
    parser.add_argument("--index", type=int, default=0, help="the sample")
    parser.add_argument("--out", default="docs/parallax.jpg")
    args = parser.parse_args()
    config = load_config(args.config, image_size=tuple(args.size), n_views=args.views, depth_output=True)
    sample = SidarDataset(config=config, seed=0).sample(args.index)
    depth = sample["depth"]
    finite = depth[torch.isfinite(depth)]
    near, far = float(finite.min()), float(finite.max())
    rows = []
    for i in range(1, args.views):
        flows, valid = flow(sample, i, 0)
        shade = ((far - depth[i]) / (far - near)).clamp(0, 1) * 0.85 + 0.15
        shade = torch.where(torch.isfinite(depth[i]), shade, torch.zeros_like(shade)).expand(3, -1, -1)
        longest = float(flows.nan_to_num(0.0).norm(dim=0).max())
        columns = [sample["images"][i], shade, flow_colours(flows, valid, longest), valid.float().expand(3, -1, -1),
                   read_along(sample["images"][0], flows, valid)]
        rows.append(torch.cat(columns, dim=2))
    grid = torch.cat(rows, dim=1)
    pixels = grid.mul(255).round().byte().permute(1, 2, 0).numpy()
    Image.fromarray(pixels).save(args.out, quality=90)
    print(f"{args.out}: sample {args.index} of {args.config} (seed 0), views 1..{args.views - 1} to view 0, "
          f"depth {near:.3f}..{far:.3f} painting units")


if __name__ == "__main__":
    main()
