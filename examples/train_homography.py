"""Train a deep homography network on sidar_torch pairs, the short version of the shipped ``sidar-net``.

    python examples/train_homography.py            # 300 steps on 40 rendered sequences (minutes on 2 cores)
    python examples/train_homography.py --quick    # a smoke run (seconds)

The same code as ``python -m benchmarks.transfer train`` (which made the shipped ``sidar-net`` and
``warp-net``, 1500 steps on 400 sequences each), with fewer steps: render ``misaligned`` sequences
into memory, cut patch-protocol pairs from them (a 128 x 128 box of view i; the same box of view j
brought back by ``H_ij`` and its corners moved by up to 32 px), train a
:class:`~sidar_torch.deep_homography.network.CornerNet`, and score it against the identity on pairs
of sequences it did not see. ``--save PATH`` keeps the weights; any function
``estimate(source, target) -> H`` around them can be scored with ``python -m sidar_torch evaluate
--estimator MODULE:FUNCTION --protocol patches``.
"""

from __future__ import annotations

import argparse
import time

import torch
from torch.utils.data import DataLoader

from sidar_torch import SidarDataset, load_config
from sidar_torch.deep_homography.training import SidarPairs, TrainSettings, protocol_errors, train


def render(first: int, count: int, size: tuple[int, int], workers: int) -> dict[str, torch.Tensor]:
    """``count`` 6-view ``misaligned`` sequences from index ``first``: uint8 ``images (S, 6, 3, H, W)``, uint8
    ``masks (S, 6, 1, H, W)``, float64 ``homographies (S, 6, 6, 3, 3)``."""
    dataset = SidarDataset(source=None, config=load_config("misaligned", image_size=size, n_views=6), seed=0)
    loader = DataLoader(Sequences(dataset, first, count), batch_size=None, num_workers=workers)
    samples = list(loader)
    return {key: torch.stack([s[key] for s in samples]) for key in samples[0]}


class Sequences(torch.utils.data.Dataset):
    """Samples ``first .. first + count - 1`` of ``dataset``, kept as 8-bit views, masks and homographies."""

    def __init__(self, dataset: SidarDataset, first: int, count: int):
        self.dataset, self.first, self.count = dataset, first, count

    def __len__(self) -> int:
        return self.count

    def __getitem__(self, k: int) -> dict[str, torch.Tensor]:
        sample = self.dataset.sample(self.first + k)
        return {"images": (sample["images"] * 255).round().byte(), "masks": sample["masks"].byte(),
                "homographies": sample["homographies"].double()}


def main(argv: list[str] | None = None) -> dict[str, float]:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="a smoke run: 2 sequences, small patches, 3 steps")
    parser.add_argument("--save", metavar="PATH", help="write the trained weights (a state dict) to PATH")
    args = parser.parse_args(argv)
    # (image size, patch, rho, training sequences, steps, batch, workers)
    size, patch, rho, count, steps, batch, workers = (((96, 128), 32, 8, 2, 3, 4, 0) if args.quick else
                                                      ((384, 512), 128, 32, 40, 300, 32, 2))
    start = time.perf_counter()
    training, held_out = render(1000, count, size, workers), render(5000, max(1, count // 4), size, workers)
    print(f"rendered {count} + {max(1, count // 4)} sequences in {time.perf_counter() - start:.0f} s")
    pairs = SidarPairs(training["images"], training["masks"], training["homographies"], patch=patch, rho=rho)
    report = lambda step, loss, seconds: print(f"step {step}: loss {loss:.2f} px, {seconds:.0f} s")  # noqa: E731
    network = train(pairs, TrainSettings(steps=steps, batch=batch, checkpoint_every=max(1, steps // 10)), None, report)
    if args.save:
        torch.save(network.state_dict(), args.save)
        print(f"wrote {args.save}")
    sequences = [{key: value[k] for key, value in held_out.items()} for k in range(len(held_out["images"]))]
    scores = {name: float(protocol_errors(model, sequences, patch, rho).mean())
              for name, model in (("network", network), ("identity", None))}
    print(f"held-out MACE: network {scores['network']:.2f} px, identity {scores['identity']:.2f} px")
    return scores


if __name__ == "__main__":
    main()
