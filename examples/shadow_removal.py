"""Shadow removal: a small network learns to turn SIDAR views into their shadow-free twins.

    python examples/shadow_removal.py [--quick] [--steps N]

Every view comes with ``shadow_free`` (the same view with no light blocked, same view effects) and
``shadow_masks`` (the fraction of the direct light occluders block), the triplet shadow datasets
such as ISTD photograph a few thousand times. A 5-layer convolutional network predicts a per-pixel
gain and offset from the view (it starts as the identity, the do-nothing baseline) and is trained
with an L1 loss against ``shadow_free``, plus, as optional supervision, a mask head against
``shadow_masks``. It prints, on held-out samples, the L1 error (0-255 levels) against the shadow-free
view over the shadowed painting pixels (mask >= 0.1) and over all pixels, for the trained network
and for doing nothing, and returns them.
"""

from __future__ import annotations

import argparse
import time

import torch
from torch import nn
from torch.utils.data import DataLoader

from sidar_torch import SidarDataset, load_config


class ShadowRemover(nn.Module):
    """``(N, 3, H, W)`` views in [0, 1] -> (shadow-free estimate ``(N, 3, H, W)``, shadow mask logits
    ``(N, 1, H, W)``). The estimate is ``view * (1 + gain) + offset``; both start at 0."""

    def __init__(self, width: int = 32):
        super().__init__()
        layers, channels = [], 3
        for dilation in (1, 2, 4, 1):
            layers += [nn.Conv2d(channels, width, 3, padding=dilation, dilation=dilation), nn.ReLU()]
            channels = width
        self.body = nn.Sequential(*layers)
        self.head = nn.Conv2d(width, 7, 3, padding=1)  # gain (3), offset (3), mask logit (1)
        nn.init.zeros_(self.head.weight)
        nn.init.zeros_(self.head.bias)

    def forward(self, views: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        out = self.head(self.body(views))
        return (views * (1 + out[:, :3]) + out[:, 3:6]).clamp(0, 1), out[:, 6:]


def flat_views(batch: dict) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """A batch's views, shadow-free views, shadow masks and masks with views as batch items:
    ``(B V, 3, H, W)``, ``(B V, 3, H, W)``, ``(B V, 1, H, W)``, ``(B V, 1, H, W)``."""
    return tuple(batch[key].flatten(0, 1) for key in ("images", "shadow_free", "shadow_masks", "masks"))


def l1_levels(estimate: torch.Tensor, target: torch.Tensor, where: torch.Tensor) -> float:
    """Mean absolute difference in 0-255 levels over the pixels where ``where`` ``(N, 1, H, W)`` is true."""
    where = where.expand_as(target)
    return 255 * (estimate - target).abs()[where].mean().item()


def main(argv: list[str] | None = None) -> dict[str, dict[str, float]]:
    """Train, then evaluate on held-out samples; returns ``{method: {pixels: L1 levels}}``."""
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="48x64, a few steps, rendered in this process")
    parser.add_argument("--steps", type=int, default=None, help="training steps (default 600, quick 10)")
    args = parser.parse_args(argv)
    steps = args.steps if args.steps is not None else (10 if args.quick else 600)
    config = load_config("misaligned", image_size=(48, 64) if args.quick else (96, 128), n_views=2,
                         n_occluders=(1, 3), shadow_mask_output=True, shadow_free_output=True)
    workers = 0 if args.quick else 2
    train = DataLoader(SidarDataset(config=config, seed=0), batch_size=4, num_workers=workers)
    test = next(iter(DataLoader(SidarDataset(config=config, seed=1, length=16), batch_size=16, num_workers=workers)))

    torch.manual_seed(0)
    model = ShadowRemover()
    optimiser = torch.optim.Adam(model.parameters(), lr=1e-3)
    start = time.perf_counter()
    for step, batch in zip(range(steps), train):  # an endless stream of fresh samples
        views, free, shadow, _ = flat_views(batch)
        estimate, logits = model(views)
        loss = (estimate - free).abs().mean() + 0.1 * nn.functional.binary_cross_entropy_with_logits(logits, shadow)
        optimiser.zero_grad()
        loss.backward()
        optimiser.step()
        if step % 100 == 0:
            print(f"step {step}: loss {loss.item():.4f} ({time.perf_counter() - start:.0f} s)")

    views, free, shadow, masks = flat_views(test)
    with torch.no_grad():
        estimate, _ = model(views)
    shadowed = (shadow >= 0.1) & (masks == 0)
    results = {method: {"shadowed painting pixels": l1_levels(out, free, shadowed),
                        "all pixels": l1_levels(out, free, torch.ones_like(masks, dtype=torch.bool))}
               for method, out in (("trained network", estimate), ("do nothing (the view itself)", views))}
    print(f"\n{steps} steps in {time.perf_counter() - start:.0f} s; {shadowed.float().mean().item():.1%} of the "
          f"held-out pixels are shadowed painting\n")
    print("| method | L1 on shadowed painting pixels (levels) | L1 on all pixels (levels) |\n|---|---|---|")
    for method, row in results.items():
        print(f"| {method} | {row['shadowed painting pixels']:.2f} | {row['all pixels']:.2f} |")
    return results


if __name__ == "__main__":
    main()
