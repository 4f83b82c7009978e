"""Does the data teach? One network, one budget, two data arms (issue #45).

    python -m benchmarks.transfer train [--steps N] [--sequences S] [--out out/transfer]
    python -m benchmarks.transfer table [--paper DIR] [--out out/transfer] [--markdown FILE]

``train`` renders the training sequences once (``misaligned``, 384 x 512, 6 views, procedural
paintings 1000 .. 1000 + S - 1, seed 0; kept in ``OUT``), then trains the same
:class:`sidar_torch.deep_homography.network.CornerNet` with the same settings twice: on protocol
pairs of those sequences (``sidar-net``) and on the classic 2-D recipe on the same paintings
(``warp-net``). Progress, wall and CPU time are printed; checkpoints in ``OUT`` make it resumable
(run the same command again). Each arm ends with its score on held-out data of both kinds (24
sequences of paintings 5000-5023; ``warps-v1``), beside the identity's, and its weights in ``OUT``.

``table`` scores ``sidar-net``, ``warp-net`` (the package's shipped weights, or ``--weights OUT``),
SIFT + RANSAC and the identity with the patch protocol on ``warps-v1``, ``homography-v1`` and, with
``--paper DIR``, a folder in the SIDAR paper's layout, with 90 % bootstrap intervals over pairs.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np
import torch
from torch.utils.data import DataLoader, Dataset

from sidar_torch import SidarDataset, load_config
from sidar_torch.deep_homography.protocol import cut_pair, draw_pairs
from sidar_torch.deep_homography.training import SidarPairs, TrainSettings, WarpPairs, train
from sidar_torch.deep_homography.warps import WarpTestSet
from sidar_torch.paintings import ProceduralPaintings

PRESET = "misaligned"
"""The sidar arm's preset (see docs/benchmarks.md for why not ``paper_misaligned``)."""
IMAGE_SIZE = (384, 512)
TRAIN_FIRST = 1000
HELD_OUT_FIRST = 5000


class _Sequences(Dataset):
    """Sequences ``first .. first + count - 1`` of ``preset`` (6 views, :data:`IMAGE_SIZE`) as 8-bit views and masks."""

    def __init__(self, preset: str, first: int, count: int):
        config = load_config(preset, image_size=IMAGE_SIZE, n_views=6)
        self.dataset = SidarDataset(source=None, config=config, seed=0)
        self.first, self.count = first, count

    def __len__(self) -> int:
        return self.count

    def __getitem__(self, k: int) -> dict[str, torch.Tensor]:
        sample = self.dataset.sample(self.first + k)
        return {"images": (sample["images"] * 255).round().to(torch.uint8),
                "masks": sample["masks"].to(torch.uint8), "homographies": sample["homographies"].double()}


def render(preset: str, first: int, count: int, path: Path) -> dict[str, torch.Tensor]:
    """The sequences (see :class:`_Sequences`), rendered by 2 DataLoader workers once and kept at ``path``."""
    if path.is_file():
        return torch.load(path, weights_only=True)
    start = time.perf_counter()
    parts: dict[str, list[torch.Tensor]] = {"images": [], "masks": [], "homographies": []}
    for k, batch in enumerate(DataLoader(_Sequences(preset, first, count), batch_size=8, num_workers=2)):
        for key in parts:
            parts[key].append(batch[key])
        print(f"  rendered {min((k + 1) * 8, count)} / {count} sequences, {time.perf_counter() - start:.0f} s",
              flush=True)
    sequences = {key: torch.cat(value) for key, value in parts.items()}
    torch.save(sequences, path)
    return sequences


def paintings(first: int, count: int) -> torch.Tensor:
    """``(count, 3, H, W)`` uint8: the procedural paintings ``first ..`` at :data:`IMAGE_SIZE`."""
    source = ProceduralPaintings()
    return torch.stack([torch.from_numpy(source.painting(first + k, IMAGE_SIZE)).permute(2, 0, 1)
                        for k in range(count)])


@torch.no_grad()
def held_out_errors(network: torch.nn.Module | None, sequences) -> np.ndarray:
    """Corner errors (pixels, the mean of the four corners' distances) of ``network`` (``None``: the
    identity) on the protocol's pairs of ``sequences`` (seed 0)."""
    errors = []
    for k in range(len(sequences)):
        sample = sequences[k]
        images = sample["images"].float() / 255 if sample["images"].dtype == torch.uint8 else sample["images"]
        sample = {**sample, "images": images, "masks": sample["masks"].float()}
        for pair in draw_pairs(sample, k):
            cut = cut_pair(images, sample["homographies"][pair.source, pair.target].double().numpy(), pair)
            truth = torch.from_numpy(pair.offsets).float()
            estimate = torch.zeros(4, 2) if network is None else network(cut["source"][None], cut["target"][None])[-1, 0]
            errors.append(float((estimate - truth).norm(dim=-1).mean()))
    return np.array(errors)


class _Indexed:
    """``dict`` of stacked tensors -> an indexable of per-sequence dicts."""

    def __init__(self, stacked: dict[str, torch.Tensor]):
        self.stacked = stacked

    def __len__(self) -> int:
        return len(self.stacked["images"])

    def __getitem__(self, k: int) -> dict[str, torch.Tensor]:
        return {key: value[k] for key, value in self.stacked.items()}


def _train(args: argparse.Namespace) -> None:
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    torch.set_num_threads(args.threads)
    wall, cpu = time.perf_counter(), time.process_time()
    print(f"rendering {args.sequences} training and 24 held-out sequences ({args.preset}, "
          f"{IMAGE_SIZE[0]}x{IMAGE_SIZE[1]})", flush=True)
    sequences = render(args.preset, TRAIN_FIRST, args.sequences, out / f"sequences-{args.preset}-{args.sequences}.pt")
    held_out = _Indexed(render(args.preset, HELD_OUT_FIRST, 24, out / f"held-out-{args.preset}.pt"))
    print(f"rendered in {time.perf_counter() - wall:.0f} s wall (this process's CPU {time.process_time() - cpu:.0f} s; "
          f"the workers' is not counted)", flush=True)
    settings = TrainSettings(steps=args.steps, batch=args.batch, seed=args.seed)
    arms = {"sidar-net": SidarPairs(sequences["images"], sequences["masks"], sequences["homographies"]),
            "warp-net": WarpPairs(paintings(TRAIN_FIRST, args.sequences))}
    warps = WarpTestSet(count=24)
    identity = {"sidar held-out": held_out_errors(None, held_out), "warps-v1 (24)": held_out_errors(None, warps)}
    for name in args.arms:
        wall, cpu = time.perf_counter(), time.process_time()

        def report(step: int, loss: float, seconds: float) -> None:
            print(f"  {name}: step {step} / {settings.steps}, loss {loss:.2f} px, {seconds:.0f} s training "
                  f"(this run: {time.perf_counter() - wall:.0f} s wall, {time.process_time() - cpu:.0f} s CPU)",
                  flush=True)

        print(f"training {name}: {settings}", flush=True)
        network = train(arms[name], settings, out / f"{name}.ckpt", report)
        torch.save(network.state_dict(), out / f"{name}.pt")
        for label, data in (("sidar held-out", held_out), ("warps-v1 (24)", warps)):
            errors = held_out_errors(network, data)
            print(f"  {name} on {label}: MACE {errors.mean():.2f} px (identity {identity[label].mean():.2f}), "
                  f"median {np.median(errors):.2f}, {len(errors)} pairs", flush=True)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    commands = parser.add_subparsers(dest="command", required=True)
    training = commands.add_parser("train", help="render, train both arms, score them on held-out data")
    training.add_argument("--steps", type=int, default=1500)
    training.add_argument("--batch", type=int, default=32)
    training.add_argument("--sequences", type=int, default=400)
    training.add_argument("--preset", default=PRESET, help=f"the sidar arm's preset (default {PRESET})")
    training.add_argument("--seed", type=int, default=0)
    training.add_argument("--threads", type=int, default=os.cpu_count() or 1)
    training.add_argument("--arms", nargs="+", default=["sidar-net", "warp-net"], choices=["sidar-net", "warp-net"])
    training.add_argument("--out", default="out/transfer")
    args = parser.parse_args(argv)
    if args.command == "train":
        _train(args)
    else:  # pragma: no cover - argparse's choices
        sys.exit(2)


if __name__ == "__main__":
    main()
