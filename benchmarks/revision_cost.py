"""What a code change costs: CPU time per view of the same samples rendered by two checkouts of the
repository, alternated in fresh processes. ``python -m benchmarks.revision_cost --trees A B
[--config P] [--size HxW] [--samples N] [--rounds R]`` from the repository root.

For changes that :mod:`benchmarks.setting_cost` (two settings of one renderer, one process) cannot compare in one
process: a shader edit, a scene sampler that draws differently. Each round runs, for each tree in
turn, one process that imports ``sidar_torch`` from that tree, makes one warm-up sample (start-up,
shaders) and then samples ``0 .. N - 1`` of ``SidarDataset(config=P at HxW, seed=0)``, timing each
in the process's CPU time (one thread: ``common.one_thread``, llvmpipe in the calling thread). Printed:
per tree and round the median per view and the total, then per tree the median of its rounds' totals
and the ratio ``B / A``. A tree is any folder holding a checkout, e.g. ``git worktree add --detach
/tmp/before HEAD~3``. ``--env-a``/``--env-b NAME=VALUE`` set an environment variable in one side's
processes only, so one tree can be compared with itself under two settings of the environment
(e.g. PyOpenGL's ``PYOPENGL_USE_ACCELERATE=0``).

    python -m benchmarks.revision_cost --trees /tmp/before . --config paper_misaligned --samples 16 --rounds 3
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

from .common import DEFAULT_PRESET, machine, machine_line, median, parse_size, size_label

_CHILD = """
import json, sys, time
tree, preset, size, samples = sys.argv[1], sys.argv[2], tuple(json.loads(sys.argv[3])), int(sys.argv[4])
sys.path.insert(0, tree)
import sidar_torch
from sidar_torch import SidarDataset, load_config
if not sidar_torch.__file__.startswith(tree):
    raise SystemExit(f"revision_cost: imported {sidar_torch.__file__}, not the tree {tree}")
import torch
torch.set_num_threads(1)
config = load_config(preset, image_size=size)
dataset = SidarDataset(config=config, seed=0)
dataset.warm_up()  # every shader variant (a fresh process's first sample would come before it)
dataset.sample(10 ** 6)  # warm-up: start-up
times = []
for index in range(samples):
    start = time.process_time()
    dataset.sample(index)
    times.append(time.process_time() - start)
print(json.dumps({"views": config.n_views, "seconds": times}))
"""
"""The measuring process: prints ``{"views": V, "seconds": [per sample]}`` as its last line."""


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``python -m benchmarks.revision_cost``; parsing it runs nothing."""
    parser = argparse.ArgumentParser(prog="python -m benchmarks.revision_cost", description=__doc__.splitlines()[0])
    parser.add_argument("--trees", nargs=2, required=True, metavar=("A", "B"), help="two checkouts: before and after")
    parser.add_argument("--config", default=DEFAULT_PRESET, help=f"preset name or YAML path (default {DEFAULT_PRESET})")
    parser.add_argument("--size", type=parse_size, default=(384, 512), metavar="HxW", help="image size (default 384x512)")
    parser.add_argument("--samples", type=int, default=16, help="measured samples per process (default 16)")
    parser.add_argument("--rounds", type=int, default=3, help="processes per tree, alternated (default 3)")
    for side in "ab":
        parser.add_argument(f"--env-{side}", action="append", type=_assignment, default=[], metavar="NAME=VALUE",
                            help=f"an environment variable for tree {side.upper()}'s processes only (repeatable)")
    return parser


def _assignment(text: str) -> tuple[str, str]:
    """``NAME=VALUE`` as ``(NAME, VALUE)``."""
    name, sep, value = text.partition("=")
    if not sep or not name:
        raise argparse.ArgumentTypeError(f"expected NAME=VALUE, got {text!r}")
    return name, value


def measure(tree: Path, preset: str, size: tuple[int, int], samples: int,
            env: dict[str, str] | None = None) -> tuple[int, list[float]]:
    """Views per sample and the CPU seconds of each of ``samples`` samples, measured by a fresh process
    importing ``sidar_torch`` from ``tree`` (with ``env`` added to this process's environment)."""
    result = subprocess.run([sys.executable, "-c", _CHILD, str(tree), preset, json.dumps(size), str(samples)],
                            capture_output=True, text=True, check=False, env={**os.environ, **(env or {})})
    if result.returncode != 0:
        raise SystemExit(f"revision_cost: the process for {tree} failed:\n{result.stderr[-2000:]}")
    out = json.loads(result.stdout.strip().splitlines()[-1])
    return out["views"], out["seconds"]


def main(argv: list[str] | None = None) -> None:
    args = build_parser().parse_args(argv)
    trees = [Path(t).resolve() for t in args.trees]
    for tree in trees:
        if not (tree / "sidar_torch" / "__init__.py").is_file():
            raise SystemExit(f"revision_cost: --trees: {tree} holds no sidar_torch package")
    if args.samples < 1 or args.rounds < 1:
        raise SystemExit("revision_cost: --samples and --rounds must be at least 1")
    envs = [dict(args.env_a), dict(args.env_b)]
    before = machine()
    totals: list[list[float]] = [[], []]
    print(f"{args.config} at {size_label(args.size)}, {args.samples} samples per process, {args.rounds} rounds")
    for round_ in range(args.rounds):
        for side, (tree, env) in enumerate(zip(trees, envs)):
            views, seconds = measure(tree, args.config, args.size, args.samples, env)
            totals[side].append(sum(seconds))
            setting = "".join(f" {name}={value}" for name, value in env.items())
            print(f"round {round_ + 1} {'AB'[side]} {tree}{setting}: median {1e3 * median(seconds) / views:.2f} ms/view, "
                  f"total {sum(seconds):.2f} s")
    a, b = (median(side) for side in totals)
    print(f"median total: A {a:.2f} s, B {b:.2f} s; B / A = {b / a:.3f}")
    print(machine_line(before, machine()))


if __name__ == "__main__":
    main()
