"""``SidarAugment`` on one batch: its own cost against ``SidarDataset.sample`` of the same scenes, and a
render pool of ``--workers`` processes against rendering in the calling process.

Prints, for a batch of ``--batch`` random images (``--views`` views at ``--size``, preset ``--preset``):

* **own cost**: process CPU time per image of a ``SidarAugment`` call (``num_workers=0``) and of
  ``SidarDataset(source=the same images).sample`` drawing the same scenes (its generator set to the
  module's ``[seed, call, b]``): what the module adds to rendering (checks, 8-bit conversion, fitting,
  stacking) is their difference;
* **pool**: median wall time per call with ``num_workers=0`` and ``--workers``, the CPU time of this
  process, and that of this process plus the workers (from ``/proc``), and the wall-clock speedup.

Every figure is a median over ``--calls`` calls after one warm-up call (shaders; the pool's start).
Run at the repository root: ``python -m benchmarks.augment_pool`` (``--help`` for the options).
"""

from __future__ import annotations

import argparse
import os
import time
from typing import Callable, Sequence

import numpy as np
import torch

from sidar_torch import SidarAugment, SidarDataset

from .common import DEFAULT_PRESET, cpu_seconds, machine, machine_line, median, one_thread, parse_size, size_label

__all__ = ["build_parser", "main", "measure"]


def _process_cpu_seconds(pid: int) -> float:
    """User + system CPU seconds of process ``pid`` so far (``/proc/<pid>/stat``)."""
    with open(f"/proc/{pid}/stat") as stat:
        fields = stat.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _timed(call: Callable[[], object], workers: Sequence[int]) -> tuple[float, float, float]:
    """Wall seconds, this process's CPU seconds and those of this process plus ``workers`` for one ``call()``."""
    before = sum(_process_cpu_seconds(pid) for pid in workers)
    wall, cpu = time.perf_counter(), time.process_time()
    call()
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    return wall, cpu, cpu + sum(_process_cpu_seconds(pid) for pid in workers) - before


def measure(preset: str, batch: int, views: int, size: tuple[int, int], workers: int, calls: int,
            seed: int = 0) -> dict[str, float]:
    """The figures :func:`main` prints (seconds), see the module docstring."""
    images = torch.rand(batch, 3, *size, generator=torch.Generator().manual_seed(seed))
    figures: dict[str, float] = {}
    with one_thread():
        serial = SidarAugment(preset, seed=seed, n_views=views, image_size=size)
        dataset = SidarDataset(source=images, config=serial.config, seed=seed)
        serial(images)  # warm-up
        own, through_dataset = [], []
        for call in range(1, calls + 1):
            serial.calls = call
            own.append(cpu_seconds(lambda: serial(images)))
            dataset.generator = lambda index, call=call: np.random.default_rng([seed, call, index])
            through_dataset.append(cpu_seconds(lambda: [dataset.sample(b) for b in range(batch)]))
        figures["augment_cpu_per_image"] = median(own) / batch
        figures["dataset_cpu_per_image"] = median(through_dataset) / batch
        with SidarAugment(preset, seed=seed, n_views=views, image_size=size, num_workers=workers) as pooled:
            pooled(images)  # warm-up: starts the pool, shaders in every worker
            pids = [p.pid for p in pooled._pool.processes]
            for name, module, watched in (("serial", serial, []), ("pool", pooled, pids)):
                rows = [_timed(lambda: module(images), watched) for _ in range(calls)]
                for k, figure in enumerate(("wall", "cpu", "cpu_with_workers")):
                    figures[f"{name}_{figure}"] = median(row[k] for row in rows)
    figures["pool_speedup"] = figures["serial_wall"] / figures["pool_wall"]
    return figures


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``python -m benchmarks.augment_pool``; parsing it runs nothing."""
    parser = argparse.ArgumentParser(prog="python -m benchmarks.augment_pool", description=__doc__.split("\n\n")[0])
    parser.add_argument("--preset", default=DEFAULT_PRESET)
    parser.add_argument("--batch", type=int, default=8)
    parser.add_argument("--views", type=int, default=2)
    parser.add_argument("--size", type=parse_size, default=(192, 256), help="HxW (default 192x256)")
    parser.add_argument("--workers", type=int, default=2, help="render processes of the pool (default 2)")
    parser.add_argument("--calls", type=int, default=5, help="measured calls per figure (default 5)")
    parser.add_argument("--seed", type=int, default=0)
    return parser


def main(argv: Sequence[str] | None = None) -> None:
    args = build_parser().parse_args(argv)
    before = machine()
    f = measure(args.preset, args.batch, args.views, args.size, args.workers, args.calls, args.seed)
    print(f"SidarAugment({args.preset!r}), batch {args.batch}, {args.views} views at {size_label(args.size)}, "
          f"medians of {args.calls} calls")
    print(f"own cost, CPU per image: SidarAugment {1e3 * f['augment_cpu_per_image']:.1f} ms, "
          f"SidarDataset.sample of the same scenes {1e3 * f['dataset_cpu_per_image']:.1f} ms "
          f"(ratio {f['augment_cpu_per_image'] / f['dataset_cpu_per_image']:.3f})")
    for name, label in (("serial", "num_workers=0"), ("pool", f"num_workers={args.workers}")):
        print(f"{label}: wall {1e3 * f[f'{name}_wall']:.0f} ms per call, CPU of this process "
              f"{1e3 * f[f'{name}_cpu']:.0f} ms, with the workers {1e3 * f[f'{name}_cpu_with_workers']:.0f} ms")
    print(f"pool speedup (wall, num_workers={args.workers} over 0): {f['pool_speedup']:.2f}x")
    print(machine_line(before, machine()))


if __name__ == "__main__":
    main()
