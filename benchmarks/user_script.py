"""What a user's training script gets: ``python -m benchmarks.user_script`` from the repository root.

A plain process, as a user's script is: the heap as glibc leaves it (no setting the package does not
apply itself), a parent that never renders, DataLoader workers forked from it. It measures, on the
consumer's side (wall clock):

* **first sample**: from ``iter(loader)`` to the first sample received, with fresh workers whose
  parent never rendered (each compiles what its first sample needs: Mesa's disk cache decides whether
  that is a load or a compile; the run says whether the cache was on);
* **throughput**: samples received per wall second with 1 and with 2 workers, after the first
  ``--skip`` samples of each loader (start-up and warm-up), and the ratio of the two;
* **kornia**: the 2-D pipeline of :func:`benchmarks.common.kornia_pipeline` per image in this same
  plain process (median CPU time), so the rows compare with it as ``bench``'s do.

Nothing is asserted; the figures are printed (``--json PATH`` also writes them).
"""

from __future__ import annotations

import argparse
import json
import os
import time
from typing import Any

import torch
from torch.utils.data import DataLoader

from sidar_torch import SidarDataset, load_config

from .common import DEFAULT_PRESET, cpu_seconds, kornia_call, machine, machine_line, median, one_thread, parse_size

__all__ = ["build_parser", "first_sample_seconds", "loader_throughput", "main"]


def first_sample_seconds(dataset: SidarDataset, workers: int) -> float:
    """Wall seconds from ``iter()`` of a fresh DataLoader (``workers`` processes) to its first sample."""
    loader = DataLoader(dataset, batch_size=None, num_workers=workers)
    start = time.perf_counter()
    iterator = iter(loader)
    next(iterator)
    elapsed = time.perf_counter() - start
    del iterator
    return elapsed


def loader_throughput(dataset: SidarDataset, workers: int, skip: int, samples: int) -> float:
    """Samples received per wall second by a DataLoader of ``workers`` processes, counted after its
    first ``skip`` samples (start-up, warm-up) over the next ``samples``."""
    iterator = iter(DataLoader(dataset, batch_size=None, num_workers=workers))
    for _ in range(skip):
        next(iterator)
    start = time.perf_counter()
    for _ in range(samples):
        next(iterator)
    rate = samples / (time.perf_counter() - start)
    del iterator
    return rate


def run(preset: str, size: tuple[int, int], samples: int, skip: int, seed: int) -> dict[str, Any]:
    """Every figure of the module docstring, in one plain process."""
    config = load_config(preset, image_size=size)
    dataset = SidarDataset(config=config, seed=seed, length=10**6)
    figures: dict[str, Any] = {"preset": preset, "size": f"{size[0]}x{size[1]}", "views": config.n_views,
                               "mesa_disk_cache_in_workers": "off" if os.environ.get("MESA_SHADER_CACHE_DISABLE", "").lower() in ("true", "1") else "on"}
    figures["first_sample_s"] = {w: first_sample_seconds(dataset, w) for w in (1, 2)}
    rates = {w: loader_throughput(dataset, w, skip, samples) for w in (1, 2)}
    figures["samples_per_s"] = rates
    figures["worker_scaling"] = rates[2] / rates[1]
    with one_thread():
        call = kornia_call(1, size, seed)
        figures["kornia_ms_per_image"] = 1e3 * median(cpu_seconds(call) for _ in range(20))
    # One worker's wall seconds per sample, per view, against kornia's CPU per image (one core each).
    figures["ms_per_view_1_worker"] = 1e3 / rates[1] / config.n_views
    figures["kornia_ratio_1_worker"] = figures["ms_per_view_1_worker"] / figures["kornia_ms_per_image"]
    return figures


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``python -m benchmarks.user_script``."""
    parser = argparse.ArgumentParser(prog="python -m benchmarks.user_script", description=__doc__.split("\n\n")[0])
    parser.add_argument("--preset", default=DEFAULT_PRESET)
    parser.add_argument("--size", type=parse_size, default=(384, 512), metavar="HxW")
    parser.add_argument("--samples", type=int, default=24, help="samples timed per loader (default 24)")
    parser.add_argument("--skip", type=int, default=4, help="samples of each loader not timed (default 4)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", default=None, metavar="PATH")
    return parser


def main(argv: list[str] | None = None) -> None:
    args = build_parser().parse_args(argv)
    before = machine()
    figures = run(args.preset, args.size, args.samples, args.skip, args.seed)
    figures["machine"] = machine_line(before, machine())
    print(json.dumps(figures, indent=1))
    if args.json:
        with open(args.json, "w") as out:
            json.dump(figures, out, indent=1)


if __name__ == "__main__":
    torch.set_num_threads(1)
    main()
