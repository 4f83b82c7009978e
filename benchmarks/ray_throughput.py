"""Sequences per second through Ray (``sidar_torch.io.cluster.ray_dataset``) with 1 and 2 actors on a
local Ray cluster of ``--cpus`` CPUs, against ``SidarDataset`` in this process and through a
DataLoader with as many workers as the cluster has CPUs, in the same run.

For each way, ``--count`` sequences (``--views`` views at ``--size``, preset ``--preset``) reach
this process as sample tensors (``SidarDataset``'s dicts; Ray: rows of 8-bit arrays turned into
them by ``torch_batches``), ``--repeats`` times, each time by a fresh pipeline (new actors, new workers), and two
figures are taken per run: **start-up**, the wall time from asking to the first sequence (Ray:
scheduling the actors, importing the package, making the renderer; DataLoader: forking the
workers, making the renderer), **steady**, the sequences per second over the second half of the
run (the first half ends in a burst of what a pipeline rendered ahead), and **overall**, all the
sequences over the whole run (wall time). Printed: medians over the repeats, and each
steady rate as a ratio to this process's. Wall-clock figures: run on an idle machine and read the
load average printed last. Run at the repository root: ``python -m benchmarks.ray_throughput``.
"""

from __future__ import annotations

import argparse
import time
from typing import Callable, Iterable, Sequence

from torch.utils.data import DataLoader

from sidar_torch import SidarDataset, load_config

from .common import DEFAULT_PRESET, machine, machine_line, median, one_thread, parse_size, size_label

__all__ = ["build_parser", "main", "measure"]


def _arrivals(items: Iterable[object]) -> list[float]:
    """``time.perf_counter()`` at the arrival of each item, the first entry being the time of asking."""
    times = [time.perf_counter()]
    for _ in items:
        times.append(time.perf_counter())
    return times


def _figures(runs: list[list[float]]) -> dict[str, float]:
    """Medians over runs of :func:`_arrivals`: start-up (s, asking to the first sequence), steady rate
    (sequences/s over the second half of the run: a pipeline that renders ahead hands its first
    sequences over in a burst, so the first half would flatter it) and overall rate (all sequences
    over the whole run, start-up included)."""
    def steady(t: list[float]) -> float:
        half = (len(t) - 1) // 2
        return (len(t) - 1 - half) / (t[-1] - t[half])

    return {"startup_s": median(t[1] - t[0] for t in runs), "steady_per_s": median(map(steady, runs)),
            "overall_per_s": median((len(t) - 1) / (t[-1] - t[0]) for t in runs)}


def measure(preset: str, size: tuple[int, int], views: int, count: int, repeats: int, cpus: int = 2,
            seed: int = 0) -> dict[str, dict[str, float]]:
    """``{way: {"startup_s": ..., "steady_per_s": ..., "overall_per_s": ..., "ratio": ...}}`` for the ways of the module
    docstring: ``"one process"``, ``"DataLoader, <cpus> workers"``, ``"Ray, 1 actor"``, ``"Ray, <cpus> actors"``.
    Starts a local Ray cluster of ``cpus`` CPUs (unless this process already joined one) and shuts it
    down at the end if it started it."""
    import ray

    from sidar_torch.io.cluster import ray_dataset, torch_batches

    if count < 4:
        raise ValueError(f"count: expected at least 4 sequences (a start-up and a second half), got {count}")
    dataset = SidarDataset(config=load_config(preset, image_size=size, n_views=views), seed=seed, length=count)
    ways: dict[str, Callable[[], Iterable[object]]] = {
        "one process": lambda: iter(dataset),
        f"DataLoader, {cpus} workers": lambda: DataLoader(dataset, batch_size=None, num_workers=cpus),
        "Ray, 1 actor": lambda: torch_batches(ray_dataset(dataset, count, actors=1), batch_size=1),
        f"Ray, {cpus} actors": lambda: torch_batches(ray_dataset(dataset, count, actors=cpus), batch_size=1),
    }
    started = not ray.is_initialized()
    if started:
        ray.init(num_cpus=cpus, include_dashboard=False, log_to_driver=False)
    ray.data.DataContext.get_current().enable_progress_bars = False
    try:
        with one_thread():
            dataset.sample(count)  # this process's renderer and shaders, outside the figures
            figures = {way: _figures([_arrivals(make()) for _ in range(repeats)]) for way, make in ways.items()}
    finally:
        if started:
            ray.shutdown()
    base = figures["one process"]["steady_per_s"]
    for row in figures.values():
        row["ratio"] = row["steady_per_s"] / base
    return figures


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``python -m benchmarks.ray_throughput``; parsing it runs nothing."""
    parser = argparse.ArgumentParser(prog="python -m benchmarks.ray_throughput", description=__doc__.split("\n\n")[0])
    parser.add_argument("--preset", default=DEFAULT_PRESET)
    parser.add_argument("--size", type=parse_size, default=(192, 256), help="HxW (default 192x256)")
    parser.add_argument("--views", type=int, default=6, help="views per sequence (default 6)")
    parser.add_argument("--count", type=int, default=24, help="sequences per run (default 24)")
    parser.add_argument("--repeats", type=int, default=3, help="runs per way (default 3)")
    parser.add_argument("--cpus", type=int, default=2, help="CPUs of the local Ray cluster and DataLoader workers")
    parser.add_argument("--seed", type=int, default=0)
    return parser


def main(argv: Sequence[str] | None = None) -> None:
    args = build_parser().parse_args(argv)
    before = machine()
    figures = measure(args.preset, args.size, args.views, args.count, args.repeats, args.cpus, args.seed)
    print(f"{args.preset!r}, {args.views} views at {size_label(args.size)}, {args.count} sequences per run, "
          f"medians of {args.repeats} runs; local Ray cluster of {args.cpus} CPUs")
    print("| way | start-up (s) | steady (sequences/s) | steady / one process | overall (sequences/s) |")
    print("|---|---|---|---|---|")
    for way, row in figures.items():
        print(f"| {way} | {row['startup_s']:.2f} | {row['steady_per_s']:.2f} | {row['ratio']:.2f} | "
              f"{row['overall_per_s']:.2f} |")
    print(machine_line(before, machine()))


if __name__ == "__main__":
    main()
