"""HomographyNet on SIDAR pairs against HomographyNet on random-corner pairs, on CPU in a few minutes.

    python examples/train_homography.py            # the full run (about 5 minutes on 2 cores)
    python examples/train_homography.py --quick    # a smoke run (seconds)
    python examples/train_homography.py --save ~/.cache/sidar_torch/homographynet.pt  # keep the weights

Two copies of one small HomographyNet-style regressor (DeTone et al. 2016: two 64 x 64 grey
patches in, the four corners' displacements out) are trained from scratch, on

- SIDAR pairs: ``homography_pairs`` cut out of 128 x 96, 3-view sequences of the ``misaligned``
  preset (lights with shadows, 1-3 occluders per view, a fresh scene per view), with the camera
  motion narrowed (tilt <= 30 degrees, field of view 65-85 degrees) so that corners move about as
  far as in the other set; of 4 candidate pairs per draw, the first whose patch sees the painting
  in both views for at least half its pixels (else the best);
- random-corner pairs, the usual synthetic recipe, from the same paintings: a 64 x 64 box at least
  16 px inside the painting, its corners moved by up to +-16 px each (uniform per coordinate, the
  paper's +-rho with rho a quarter of the patch), the painting warped by that homography.

Both train on the same number of pairs, drawn once from the same paintings, and both are
evaluated on fixed held-out pairs of each kind, from paintings and scenes not used in training.
It prints the mean corner error (pixels, the mean over the four corners of the distance between
the predicted and true displacement) of each model on each test set, with the medians, and that
of predicting no motion. Rendering runs once, into memory, in 2 DataLoader workers. With ``--save
PATH`` the weights of the model trained on SIDAR pairs are written to PATH: the ``homographynet``
baseline of ``python -m sidar_torch evaluate`` loads them (``SIDAR_TORCH_HOMOGRAPHYNET=PATH``).
"""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass
from pathlib import Path

import kornia
import torch
from torch import nn
from torch.utils.data import DataLoader, Dataset

from sidar_torch import SidarDataset, homography_pairs, load_config
from sidar_torch.baselines import homography_net

PATCH = 64
RHO = 16
IMAGE_SIZE = (96, 128)  # (H, W)


@dataclass(frozen=True)
class Settings:
    """Sizes of the run: paintings (one 3-view sequence each), pairs drawn from each, epochs."""

    train_paintings: int = 240
    test_paintings: int = 80
    train_pairs: int = 8
    test_pairs: int = 4
    epochs: int = 20
    batch_size: int = 64
    workers: int = 2


QUICK = Settings(train_paintings=4, test_paintings=2, train_pairs=2, test_pairs=2, epochs=1, batch_size=8, workers=0)


class _Samples(Dataset):
    """Samples ``first .. first + count - 1`` of a SidarDataset, keeping only what pairs need."""

    def __init__(self, dataset: SidarDataset, first: int, count: int):
        self.dataset, self.first, self.count = dataset, first, count

    def __len__(self) -> int:
        return self.count

    def __getitem__(self, k: int) -> dict[str, torch.Tensor]:
        sample = self.dataset.sample(self.first + k)
        return {key: sample[key] for key in ("images", "masks", "homographies", "label")}


def render(first: int, count: int, workers: int) -> dict[str, torch.Tensor]:
    """A batch of ``count`` SIDAR samples from index ``first`` on: ``images`` ``(B, 3, 3, 96, 128)``,
    ``masks`` ``(B, 3, 1, 96, 128)``, ``homographies`` ``(B, 3, 3, 3, 3)``, ``label`` ``(B, 3, 96, 128)``.
    Sample ``i`` shows painting ``i`` (the built-in procedural paintings)."""
    config = load_config("misaligned", image_size=IMAGE_SIZE, n_views=3, n_occluders=(1, 3), max_tilt_deg=30,
                         fov_deg=(65, 85), shadow_map_size=512)
    loader = DataLoader(_Samples(SidarDataset(config=config, seed=0), first, count), batch_size=count,
                        num_workers=workers)
    return next(iter(loader))


def sidar_pairs(batch: dict[str, torch.Tensor], per_sample: int, generator: torch.Generator):
    """``per_sample`` HomographyNet pairs from every sample: inputs ``(N, 2, 64, 64)``, offsets ``(N, 4, 2)`` px."""
    inputs, offsets = [], []
    for _ in range(per_sample):
        pairs = homography_pairs(batch, PATCH, generator=generator, min_valid=0.5, attempts=4)
        inputs.append(network_input(pairs["patch_a"], pairs["patch_b"]))
        offsets.append(pairs["corner_offsets"])
    return torch.cat(inputs), torch.cat(offsets)


def corner_pairs(paintings: torch.Tensor, per_image: int, generator: torch.Generator):
    """``per_image`` random-corner pairs from every painting ``(B, 3, H, W)``: inputs ``(N, 2, 64, 64)``,
    offsets ``(N, 4, 2)`` px, in the conventions of ``homography_pairs`` (corners TL, TR, BR, BL at
    pixel centres; view b is view a warped by ``H_ab``)."""
    images = paintings.repeat_interleave(per_image, 0)
    n, _, h, w = images.shape
    u0 = torch.randint(RHO, w - PATCH - RHO + 1, (n,), generator=generator)
    v0 = torch.randint(RHO, h - PATCH - RHO + 1, (n,), generator=generator)
    box = torch.tensor([[0, 0], [PATCH - 1, 0], [PATCH - 1, PATCH - 1], [0, PATCH - 1]], dtype=torch.float32)
    corners = torch.stack([u0, v0], 1).float()[:, None] + box  # (N, 4, 2)
    offsets = (torch.rand(n, 4, 2, generator=generator) * 2 - 1) * RHO
    H_ab = kornia.geometry.transform.get_perspective_transform(corners, corners + offsets)
    warped = kornia.geometry.transform.warp_perspective(images, H_ab, (h, w), align_corners=True)
    return network_input(crop(images, u0, v0), crop(warped, u0, v0)), offsets


def crop(images: torch.Tensor, u0: torch.Tensor, v0: torch.Tensor) -> torch.Tensor:
    """``(N, C, 64, 64)`` boxes with top-left pixels ``(u0, v0)`` of ``images`` ``(N, C, H, W)``."""
    return torch.stack([image[:, v:v + PATCH, u:u + PATCH] for image, u, v in zip(images, u0.tolist(), v0.tolist())])


def network_input(patch_a: torch.Tensor, patch_b: torch.Tensor) -> torch.Tensor:
    """Two RGB patches ``(N, 3, 64, 64)`` -> ``(N, 2, 64, 64)``: grey, each standardised to mean 0, std 1."""
    grey = torch.cat([kornia.color.rgb_to_grayscale(patch_a), kornia.color.rgb_to_grayscale(patch_b)], 1)
    mean, std = grey.mean((2, 3), keepdim=True), grey.std((2, 3), keepdim=True)
    return (grey - mean) / (std + 1e-3)


def train(inputs: torch.Tensor, offsets: torch.Tensor, settings: Settings, seed: int) -> nn.Module:
    """Train a fresh network on pairs ``inputs`` ``(N, 2, 64, 64)``, ``offsets`` ``(N, 4, 2)``: mean
    squared error on the displacements / 16, Adam with a cosine learning-rate decay."""
    torch.manual_seed(seed)
    generator = torch.Generator().manual_seed(seed)
    model = homography_net()
    optimizer = torch.optim.Adam(model.parameters(), lr=3e-3)
    steps_per_epoch = -(-len(inputs) // settings.batch_size)
    schedule = torch.optim.lr_scheduler.CosineAnnealingLR(optimizer, settings.epochs * steps_per_epoch)
    model.train()
    for _ in range(settings.epochs):
        order = torch.randperm(len(inputs), generator=generator)
        for batch in order.split(settings.batch_size):
            loss = nn.functional.mse_loss(model(inputs[batch]), offsets[batch].flatten(1) / RHO)
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
            schedule.step()
    return model.eval()


@torch.no_grad()
def corner_errors(model: nn.Module | None, inputs: torch.Tensor, offsets: torch.Tensor) -> torch.Tensor:
    """``(N,)`` mean corner error in pixels; ``model=None`` predicts no motion."""
    predicted = torch.zeros_like(offsets) if model is None else model(inputs).view(-1, 4, 2) * RHO
    return (predicted - offsets).norm(dim=-1).mean(-1)


def main(argv: list[str] | None = None) -> dict[str, dict[str, float]]:
    """Run the comparison and print the table; returns ``{row: {test set: mean corner error}}``."""
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="a smoke run: a few paintings, one epoch")
    parser.add_argument("--save", metavar="PATH", help="write the SIDAR-trained weights to PATH (a state dict)")
    args = parser.parse_args(argv)
    settings = QUICK if args.quick else Settings()
    start = time.perf_counter()

    train_batch = render(0, settings.train_paintings, settings.workers)
    test_batch = render(settings.train_paintings, settings.test_paintings, settings.workers)
    rendered = time.perf_counter()
    print(f"rendered {settings.train_paintings} training and {settings.test_paintings} test sequences "
          f"(3 views, 128 x 96) in {rendered - start:.0f} s")

    generator = torch.Generator().manual_seed(0)
    training = {
        "trained on SIDAR pairs": sidar_pairs(train_batch, settings.train_pairs, generator),
        "trained on random-corner pairs": corner_pairs(train_batch["label"], settings.train_pairs, generator),
    }
    tests = {
        "SIDAR test pairs": sidar_pairs(test_batch, settings.test_pairs, generator),
        "random-corner test pairs": corner_pairs(test_batch["label"], settings.test_pairs, generator),
    }
    paired = time.perf_counter()
    print(f"cut {len(training['trained on SIDAR pairs'][0])} training and {len(tests['SIDAR test pairs'][0])} test "
          f"pairs of each kind in {paired - rendered:.0f} s")
    models = {row: train(*pairs, settings, seed=0) for row, pairs in training.items()}
    if args.save:
        Path(args.save).expanduser().parent.mkdir(parents=True, exist_ok=True)
        torch.save(models["trained on SIDAR pairs"].state_dict(), Path(args.save).expanduser())
        print(f"wrote the weights of the model trained on SIDAR pairs to {args.save}")
    models["no motion (predicts 0)"] = None
    print(f"trained two models ({settings.epochs} epochs) in {time.perf_counter() - paired:.0f} s")

    results = {}
    print(f"\nmean corner error in px (median in brackets), {PATCH} x {PATCH} patches")
    print(f"| {'':32} | " + " | ".join(f"{name:>24}" for name in tests) + " |")
    print(f"|{'-' * 34}|" + "|".join("-" * 26 for _ in tests) + "|")
    for row, model in models.items():
        errors = {name: corner_errors(model, *pairs) for name, pairs in tests.items()}
        results[row] = {name: e.mean().item() for name, e in errors.items()}
        cells = [f"{e.mean().item():8.2f} ({e.median().item():5.2f})" for e in errors.values()]
        print(f"| {row:32} | " + " | ".join(f"{cell:>24}" for cell in cells) + " |")
    print(f"\ntotal {time.perf_counter() - start:.0f} s")
    return results


if __name__ == "__main__":
    main()
