"""The rendered depth's accuracy on the painting and the cost of :func:`sidar_torch.flow`: the figures of
docs/parallax.md. ``python -m benchmarks.depth_flow [--config P] [--size HxW] [--samples N]`` from the
repository root.

Renders ``--samples`` sequences with ``depth_output`` and, per view, compares the depth of every
pixel showing the painting (mask 0) with the painting plane's own camera-frame z at that pixel centre,
computed in float64 from the sample's cameras (as ``tests/render/test_depth_flow.py`` does): the
largest relative error ``|depth / plane - 1|`` of each view, then their median and maximum. Then it
times ``sidar_torch.flow(sample, i, 0)`` for every view ``i > 0`` of every sequence, ``--repeats``
times each, with torch on one thread and on two (wall and this process's CPU time, medians).

    python -m benchmarks.depth_flow --config parallax --size 384x512 --samples 8
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import torch

from sidar_torch import SidarDataset, flow

from .common import machine, machine_line, median, size_label
from .paired import paired_config, paired_parser

THREADS = (1, 2)
"""Torch thread counts ``flow`` is timed with."""


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``python -m benchmarks.depth_flow``; parsing it runs nothing."""
    parser = paired_parser("depth_flow", __doc__.splitlines()[0], samples=8, set_example="n_occluders=[0,0]")
    parser.set_defaults(config="parallax")
    parser.add_argument("--repeats", type=int, default=7, help="timed calls of flow per pair (default 7)")
    return parser


def plane_depth(K: np.ndarray, R: np.ndarray, t: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """``(H, W)`` float64: the camera-frame z of the painting plane (world z = 0) at every pixel centre
    (Kornia pixels) of the camera ``K``, ``R`` ``(3, 3)``, ``t`` ``(3,)``."""
    v, u = np.meshgrid(np.arange(size[0], dtype=float), np.arange(size[1], dtype=float), indexing="ij")
    directions = R.T @ np.linalg.solve(K, np.stack([u.ravel(), v.ravel(), np.ones(u.size)]))  # camera z = 1
    centre = -R.T @ t
    return (-centre[2] / directions[2]).reshape(size)


def depth_errors(sample: dict) -> list[float]:
    """Per view, the largest relative error of the depth on the painting's pixels (``nan``: none seen)."""
    K, R, t = (sample[key].double().numpy() for key in "KRt")
    depth, size = sample["depth"][:, 0].double().numpy(), tuple(sample["depth"].shape[-2:])
    errors = []
    for view in range(len(depth)):
        painting = sample["masks"][view, 0].numpy() == 0
        truth = plane_depth(K[view], R[view], t[view], size)
        errors.append(float(np.abs(depth[view][painting] / truth[painting] - 1).max()) if painting.any() else np.nan)
    return errors


def flow_seconds(samples: list[dict], threads: int, repeats: int) -> tuple[float, float]:
    """Median wall and CPU seconds of one ``flow(sample, i, 0)`` call, ``i > 0``, with torch on ``threads``."""
    before = torch.get_num_threads()
    torch.set_num_threads(threads)
    try:
        wall, cpu = [], []
        for sample in samples:
            for view in range(1, sample["depth"].shape[0]):
                flow(sample, view, 0)  # warm: the first call allocates
                for _ in range(repeats):
                    start_wall, start_cpu = time.perf_counter(), time.process_time()
                    flow(sample, view, 0)
                    wall.append(time.perf_counter() - start_wall)
                    cpu.append(time.process_time() - start_cpu)
        return median(wall), median(cpu)
    finally:
        torch.set_num_threads(before)


def main(argv: list[str] | None = None) -> None:
    args = build_parser().parse_args(argv)
    config = paired_config("depth_flow", args).replace(depth_output=True)
    start = machine()
    dataset = SidarDataset(config=config, seed=0)
    samples = [dataset.sample(index) for index in range(args.samples)]
    errors = [e for sample in samples for e in depth_errors(sample) if not np.isnan(e)]
    print(f"depth_flow: {args.config} {' '.join(args.set)} {size_label(config.image_size)} (H x W), {args.samples} "
          f"sequences x {config.n_views} views")
    print(f"depth on the painting: largest relative error per view, median {median(errors):.2g}, "
          f"max {max(errors):.2g} ({len(errors)} views)")
    for threads in THREADS:
        wall, cpu = flow_seconds(samples, threads, args.repeats)
        print(f"flow(sample, i, 0), {threads} thread{'s' if threads > 1 else ''}: median {wall:.3f} s wall, "
              f"{cpu:.3f} s CPU per pair ({args.repeats} calls x {len(samples) * (config.n_views - 1)} pairs)")
    print(machine_line(start, machine()))


if __name__ == "__main__":
    main()
