"""The first minute of a training script: ``python -m benchmarks.first_minute`` from the repository root.

Each run is a fresh interpreter running the README's snippet as a user's script runs it (no setting of
the benchmarks, whose own processes render in-process: here the process renders as a user's does, in
its render process, ``sidar_torch.render.process``). ``import torch`` comes first, as in a training script;
then, in wall-clock seconds:

* ``import``: ``import sidar_torch``;
* ``dataset``: ``load_config`` and ``SidarDataset(...)``;
* ``first``, ``second``, ``third``: ``ds.sample(17)``, ``ds.sample(18)``, ``ds.sample(19)``;
* ``to_first``: ``import`` + ``dataset`` + ``first``, from ``import sidar_torch`` to the first sample;
* ``worker_first``: a DataLoader of 2 workers forked by the same process, from ``iter(loader)`` to its first
  sample (each worker opens its own context: Mesa's disk cache serves the variants);
* ``worker_batch``: from there to the first batch of 2 (one sample from each worker).

The first run starts with an empty Mesa cache folder of its own (``MESA_SHADER_CACHE_DIR``, a temporary
folder): its figures are the cold cache's. The next ``--runs`` share that folder, warmed: their medians
are the figures. ``--tree DIR`` imports ``sidar_torch`` from another checkout (``git worktree add --detach
/tmp/before REV``), for the same figures of older code. Nothing is asserted; the load is printed before
and after.

    python -m benchmarks.first_minute --runs 5
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from .common import machine, machine_line, median, parse_size

__all__ = ["SCRIPT", "build_parser", "main", "run_once"]

SCRIPT = """
import json, sys, time
import torch
start = time.perf_counter()
import sidar_torch
from sidar_torch import SidarDataset, load_config
from torch.utils.data import DataLoader
imported = time.perf_counter()
config = load_config(sys.argv[1], image_size=(int(sys.argv[2]), int(sys.argv[3])), n_views=6)
ds = SidarDataset(source=None, config=config, seed=0)
made = time.perf_counter()
marks = []
for index in (17, 18, 19):
    ds.sample(index)
    marks.append(time.perf_counter())
iterator = iter(DataLoader(ds, batch_size=None, num_workers=2, timeout=600))
began = time.perf_counter()
next(iterator)
got = time.perf_counter()
next(iterator)
both = time.perf_counter()
print(json.dumps({"import": imported - start, "dataset": made - imported, "first": marks[0] - made,
                  "second": marks[1] - marks[0], "third": marks[2] - marks[1], "to_first": marks[0] - start,
                  "worker_first": got - began, "worker_batch": both - began}))
"""
"""The measured script: argv preset, height, width; prints one JSON line of seconds."""

FIGURES = ("import", "dataset", "first", "second", "third", "to_first", "worker_first", "worker_batch")


def run_once(preset: str, size: tuple[int, int], cache: Path, tree: Path | None = None) -> dict[str, float]:
    """One fresh interpreter running :data:`SCRIPT` with Mesa's cache in ``cache`` (and ``sidar_torch`` imported
    from the checkout ``tree``, if given); its seconds."""
    environment = {k: v for k, v in os.environ.items()
                   if k not in ("PYOPENGL_PLATFORM", "LP_NUM_THREADS", "MESA_SHADER_CACHE_DISABLE")}
    environment["MESA_SHADER_CACHE_DIR"] = str(cache)
    if tree is not None:
        environment["PYTHONPATH"] = str(tree)
    result = subprocess.run([sys.executable, "-c", SCRIPT, preset, str(size[0]), str(size[1])], capture_output=True,
                            text=True, env=environment, timeout=900, cwd=tree)
    if result.returncode != 0:
        raise RuntimeError(f"the measured script failed:\n{result.stderr[-3000:]}")
    return json.loads(result.stdout.strip().splitlines()[-1])


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``python -m benchmarks.first_minute``."""
    parser = argparse.ArgumentParser(prog="python -m benchmarks.first_minute", description=__doc__.split("\n\n")[0])
    parser.add_argument("--preset", default="misaligned")
    parser.add_argument("--size", type=parse_size, default=(384, 512), metavar="HxW")
    parser.add_argument("--runs", type=int, default=5, help="runs with the warmed cache (default 5)")
    parser.add_argument("--tree", type=Path, default=None, metavar="DIR",
                        help="import sidar_torch from this checkout (e.g. an older commit's git worktree)")
    return parser


def main(argv: list[str] | None = None) -> None:
    args = build_parser().parse_args(argv)
    before = machine()
    with tempfile.TemporaryDirectory() as folder:
        cold = run_once(args.preset, args.size, Path(folder), args.tree)
        warm = [run_once(args.preset, args.size, Path(folder), args.tree) for _ in range(args.runs)]
    print(f"{args.preset} {args.size[0]}x{args.size[1]}, 6 views{f', sidar_torch of {args.tree}' if args.tree else ''}: "
          f"wall seconds, cold cache (1 run) and the median "
          f"[min, max] of {args.runs} runs with the cache warm")
    for name in FIGURES:
        values = [run[name] for run in warm]
        print(f"  {name:13s} cold {cold[name]:6.2f}   warm {median(values):6.2f} [{min(values):.2f}, {max(values):.2f}]")
    print(machine_line(before, machine()))


if __name__ == "__main__":
    main()
