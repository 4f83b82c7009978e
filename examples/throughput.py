"""Samples per second of a preset, in the main process and through a DataLoader with 1 and 2 workers.

    python examples/throughput.py [--config misaligned] [--samples 12] [--size 384 512]

Prints medians of per-sample times (main process, after a warm-up sample that compiles shaders)
and wall-clock rates through the DataLoader (worker start-up included, first batch excluded).
"""

import argparse
import statistics
import time

from torch.utils.data import DataLoader

from sidar_torch import SidarDataset, load_config


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--config", default="misaligned")
    parser.add_argument("--samples", type=int, default=12)
    parser.add_argument("--size", type=int, nargs=2, default=(384, 512), metavar=("H", "W"))
    args = parser.parse_args()
    config = load_config(args.config, image_size=tuple(args.size))
    ds = SidarDataset(config=config, seed=0)
    ds.sample(10_000)  # warm-up: compiles shader variants
    times = []
    for i in range(args.samples):
        start = time.perf_counter()
        ds.sample(i)
        times.append(time.perf_counter() - start)
    median = statistics.median(times)
    print(f"{args.config} at {args.size[1]}x{args.size[0]}, {config.n_views} views per sample")
    print(f"main process: median {median:.3f} s per sample ({config.n_views / median:.1f} views/s)")
    for workers in (1, 2):
        loader = iter(DataLoader(SidarDataset(config=config, seed=0), batch_size=None, num_workers=workers))
        for _ in range(2 * workers):  # first samples of each worker include start-up and compilation
            next(loader)
        start = time.perf_counter()
        for _ in range(args.samples):
            next(loader)
        rate = args.samples / (time.perf_counter() - start)
        print(f"DataLoader, {workers} worker(s): {rate:.2f} samples/s ({rate * config.n_views:.1f} views/s)")


if __name__ == "__main__":
    main()
