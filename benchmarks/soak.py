"""Soak test: render many samples and watch memory, the C heap and GL objects.
``python -m benchmarks.soak [--samples N] [--size HxW] [--workers W]`` from the repository root.

Renders ``SidarDataset(config=<preset at --size>, seed=--seed).sample(i)`` (the built-in procedural
source, so every sample has a new painting and new lights, occluders and cameras), ``--samples`` of
them in each rendering process: this one, or with ``--workers W`` each of W DataLoader workers
(``batch_size=None``, the samples travel to this process as a training loop's do; worker ``k``
draws indices ``k, k + W, ...``). Every ``--every`` of its samples a process reports its resident
memory, glibc's heap (``mallinfo2``: bytes in use by ``malloc`` and free in its arenas; with
``--trim`` also the resident memory after ``malloc_trim(0)`` gave free pages back), the shader
programs and pooled shadow maps of its renderer, and the GL textures and buffers alive in its context. Memory growth is
measured from the end of the warm-up (``--warmup`` samples, by which time every shader variant has
been compiled and the allocators have reached their working size) to the last sample.

The renderer pools meshes (per occluder shape and count) and spot lights with their shadow
maps, so GL buffer and texture counts may rise after the warm-up while a rare scene (three
cubes in one view) first occurs; with ``--distinct D`` (``D <= --warmup``) the samples cycle
through indices ``0..D-1`` (still a new painting and scene for every sample of a cycle), every
pool is full after the warm-up, and those counts must stay exactly constant. ``--tracemalloc``
traces Python's allocations from the start and prints, per process, the ten source lines whose
live Python memory grew most from the end of the warm-up to the last sample (slower).

The last line of output is a JSON summary (``growth_mb`` and ``max_growth_mb``, the largest over
the processes; ``changed``; per report ``worker``, ``rss_mb``, ``heap_used_mb``, ``heap_free_mb``,
``programs``, ``shadow_maps``, ``gl_textures``, ``gl_buffers``, with ``--trim`` ``rss_trimmed_mb``). The exit code is 1
if the memory of a process grew by more than ``--max-growth-mb`` after the warm-up, or its program
count changed after it, or (with ``--distinct``) its shadow map, texture or buffer count did; else 0.

    python -m benchmarks.soak --samples 10000 --size 96x128 --every 500
    python -m benchmarks.soak --samples 1000 --size 192x256 --workers 2 --every 100 --warmup 200 --trim

Linux with glibc (reads ``/proc/self/statm``; the heap figures are NaN without ``mallinfo2``).
"""

from __future__ import annotations

import argparse
import ctypes
import ctypes.util
import json
import sys
import time
import tracemalloc
from typing import Iterator

from torch.utils.data import DataLoader, IterableDataset, get_worker_info

from sidar_torch import SidarDataset, load_config  # first: it selects the GL platform
from sidar_torch.render import RenderSettings, shared_renderer

from .common import DEFAULT_PRESET, parse_size, rss_mb, size_label

NAME_WINDOW = 1024
"""GL names scanned above the next free one (see :func:`count_gl_names`)."""

TOP_LINES = 10
"""Source lines listed by ``--tracemalloc``."""


def count_gl_names(is_name, gen_names, delete_names) -> int:
    """Number of live objects of one GL kind (textures, buffers) in the current context.

    GL has no "how many" query, so names are tested one by one with ``glIs*``: from 1 to
    ``NAME_WINDOW`` past the name ``glGen*`` hands out next. Mesa hands out the lowest free
    name, or the next unused one, so live names above that probe are few and near it.
    """
    probe = int(gen_names(1))
    delete_names(1, [probe])
    return sum(bool(is_name(name)) for name in range(1, probe + NAME_WINDOW))


class _MallInfo2(ctypes.Structure):
    """glibc's ``struct mallinfo2`` (``malloc.h``, glibc >= 2.33): sizes in bytes over every arena."""
    _fields_ = [(name, ctypes.c_size_t) for name in
                ("arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks", "fsmblks", "uordblks", "fordblks",
                 "keepcost")]


def _libc():
    """glibc's ``mallinfo2`` and ``malloc_trim`` as ctypes functions, or ``(None, None)`` without them."""
    name = ctypes.util.find_library("c")
    libc = ctypes.CDLL(name) if name else None
    mallinfo2, malloc_trim = getattr(libc, "mallinfo2", None), getattr(libc, "malloc_trim", None)
    if mallinfo2 is not None:
        mallinfo2.restype = _MallInfo2
    return mallinfo2, malloc_trim


def heap_mb() -> tuple[float, float]:
    """``(used, free)`` MiB of glibc's heap in this process: bytes handed out by ``malloc`` (arenas and
    its own mmaps) and bytes free inside its arenas, which the process keeps resident until
    ``malloc_trim`` or a later ``malloc`` reuses them; NaNs without ``mallinfo2``."""
    mallinfo2, _ = _libc()
    if mallinfo2 is None:
        return float("nan"), float("nan")
    info = mallinfo2()
    return (info.uordblks + info.hblkhd) / 2**20, info.fordblks / 2**20


def trimmed_rss_mb() -> float:
    """Resident memory after ``malloc_trim(0)`` returned the heap's free pages to the system, MiB
    (NaN without it). Changes no value any sample holds: it only unmaps pages nothing uses."""
    _, malloc_trim = _libc()
    if malloc_trim is None:
        return float("nan")
    malloc_trim(0)
    return rss_mb()


def report(samples: int, renderer, started: float, trim: bool) -> dict:
    """One report line's figures; the renderer's context must be current (it is after a render)."""
    from OpenGL import GL  # here, not at import: reading the command line loads no GL

    used, free = heap_mb()
    figures = {
        "samples": samples,
        "rss_mb": round(rss_mb(), 1),
        "heap_used_mb": round(used, 1),
        "heap_free_mb": round(free, 1),
        "programs": renderer.program_count,
        "shadow_maps": renderer.shadow_map_count,
        "gl_textures": count_gl_names(GL.glIsTexture, GL.glGenTextures, GL.glDeleteTextures),
        "gl_buffers": count_gl_names(GL.glIsBuffer, GL.glGenBuffers, GL.glDeleteBuffers),
        "seconds": round(time.perf_counter() - started, 1),
    }
    if trim:
        figures["rss_trimmed_mb"] = round(trimmed_rss_mb(), 1)
    return figures


class SoakStream(IterableDataset):
    """``args.samples`` samples of ``dataset`` per rendering process (this one, or each DataLoader
    worker: worker ``k`` of ``W`` draws indices ``k, k + W, ...``, cycled through ``args.distinct`` if
    given); every ``args.every``-th carries this process's :func:`report` under the key ``"soak"``
    (with ``args.tracemalloc``, the last one also ``"tracemalloc"``: the top lines of growth)."""

    def __init__(self, dataset: SidarDataset, args: argparse.Namespace):
        self.dataset, self.args = dataset, args

    def __iter__(self) -> Iterator[dict]:
        args, info = self.args, get_worker_info()
        worker, workers = (info.id, info.num_workers) if info is not None else (0, 1)
        settings = RenderSettings.from_config(self.dataset.config)
        if args.tracemalloc:
            tracemalloc.start()
        base = None
        started = time.perf_counter()
        for done in range(1, args.samples + 1):
            index = worker + (done - 1) * workers
            sample = self.dataset.sample(index % args.distinct if args.distinct else index)
            if done % args.every == 0:
                sample["soak"] = {"worker": worker, **report(done, shared_renderer(settings), started, args.trim)}
                if args.tracemalloc and done == args.warmup:
                    base = _python_snapshot()
                if args.tracemalloc and done == args.samples:
                    stats = _python_snapshot().compare_to(base, "lineno")[:TOP_LINES]
                    sample["soak"]["tracemalloc"] = [str(stat) for stat in stats]
            yield sample


def _python_snapshot() -> tracemalloc.Snapshot:
    """The Python allocations alive now, less tracemalloc's own."""
    return tracemalloc.take_snapshot().filter_traces([tracemalloc.Filter(False, tracemalloc.__file__)])


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``python -m benchmarks.soak``; parsing it runs nothing."""
    parser = argparse.ArgumentParser(prog="python -m benchmarks.soak", description=__doc__.split("\n\n")[0])
    parser.add_argument("--samples", type=int, default=10_000,
                        help="samples each rendering process renders (default 10000)")
    parser.add_argument("--size", type=parse_size, default=(384, 512), metavar="HxW",
                        help="image size, height x width in pixels (default 384x512)")
    parser.add_argument("--config", default=DEFAULT_PRESET, help=f"preset name or YAML path (default {DEFAULT_PRESET})")
    parser.add_argument("--seed", type=int, default=0, help="dataset seed (default 0)")
    parser.add_argument("--workers", type=int, default=0,
                        help="DataLoader workers that render (default 0: this process renders)")
    parser.add_argument("--every", type=int, default=500, help="report every N samples (default 500)")
    parser.add_argument("--warmup", type=int, default=None,
                        help="samples before the memory baseline (default: one report interval)")
    parser.add_argument("--distinct", type=int, default=None,
                        help="cycle through this many sample indices, at most --warmup (default: all new)")
    parser.add_argument("--trim", action="store_true",
                        help="at each report, also the resident memory after glibc's malloc_trim(0) (later reports start "
                             "from the trimmed heap)")
    parser.add_argument("--tracemalloc", action="store_true",
                        help="trace Python allocations; print the lines that grew most after the warm-up")
    parser.add_argument("--max-growth-mb", type=float, default=50.0,
                        help="largest allowed growth after the warm-up, MiB (default 50)")
    return parser


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    """The options of ``argv``, checked against each other (``--every``, ``--warmup``, ``--samples``,
    ``--distinct``, ``--workers``); a mistake exits as argparse does (code 2, one line)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    args.warmup = args.every if args.warmup is None else args.warmup
    if args.every < 1 or args.warmup < 1:
        parser.error("--every and --warmup must be >= 1")
    if args.samples <= args.warmup or (args.samples - args.warmup) % args.every or args.warmup % args.every:
        parser.error("--warmup and --samples must be multiples of --every, with --samples > --warmup")
    if args.distinct is not None and not 1 <= args.distinct <= args.warmup:
        parser.error("--distinct must be between 1 and --warmup")
    if args.workers < 0:
        parser.error("--workers must be >= 0")
    return args


def growth(reports: list[dict], warmup: int) -> tuple[float, float]:
    """``(growth, largest)`` MiB of one process's resident memory from its report at ``warmup`` samples:
    at its last report, and the largest at any report."""
    after = [r for r in reports if r["samples"] >= warmup]
    return after[-1]["rss_mb"] - after[0]["rss_mb"], max(r["rss_mb"] for r in after) - after[0]["rss_mb"]


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    dataset = SidarDataset(config=load_config(args.config, image_size=args.size), seed=args.seed)
    config = dataset.config
    where = f"in each of {args.workers} DataLoader workers" if args.workers else "in this process"
    print(f"soak: {args.samples} samples of {args.config!r} at {size_label(config.image_size)} (H x W), "
          f"{config.n_views} views, seed {args.seed}, {where}; warm-up {args.warmup}", flush=True)
    columns = ("worker", "samples", "rss_mb", "heap_used_mb", "heap_free_mb") + ("rss_trimmed_mb",) * args.trim \
        + ("programs", "shadow_maps", "gl_textures", "gl_buffers", "seconds")
    print(" ".join(f"{c:>{max(len(c), 7)}}" for c in columns))
    stream = SoakStream(dataset, args)
    if args.workers:
        stream = DataLoader(stream, batch_size=None, num_workers=args.workers)
    reports, traces = [], {}
    for sample in stream:
        if "soak" in sample:
            r = sample["soak"]
            traces[r["worker"]] = r.pop("tracemalloc", None)
            reports.append(r)
            print(" ".join(f"{r[c]:>{max(len(c), 7)}}" for c in columns), flush=True)
    per_worker = {w: [r for r in reports if r["worker"] == w] for w in sorted({r["worker"] for r in reports})}
    grown = {w: growth(rs, args.warmup) for w, rs in per_worker.items()}
    changed = sorted({key for rs in per_worker.values() for key in ("programs", "shadow_maps", "gl_textures", "gl_buffers")
                      if len({r[key] for r in rs if r["samples"] >= args.warmup}) > 1})
    failed = [key for key in changed if key == "programs" or args.distinct]
    for w, (last, largest) in grown.items():
        rs = [r for r in per_worker[w] if r["samples"] >= args.warmup]
        print(f"worker {w}: growth after warm-up {last:+.1f} MiB over {rs[-1]['samples'] - rs[0]['samples']} samples "
              f"(largest {largest:+.1f} MiB; limit {args.max_growth_mb:g} MiB); "
              f"{(rs[-1]['seconds'] - rs[0]['seconds']) / (rs[-1]['samples'] - rs[0]['samples']) * 1000:.1f} ms/sample")
        for line in traces.get(w) or ():
            print(f"  {line}")
    print(f"changed after warm-up: {', '.join(changed) or 'nothing'}")
    worst, worst_largest = max(g for g, _ in grown.values()), max(m for _, m in grown.values())
    print(json.dumps({"growth_mb": round(worst, 1), "max_growth_mb": round(worst_largest, 1), "warmup": args.warmup,
                      "changed": changed, "reports": reports}))
    return 1 if worst > args.max_growth_mb or failed else 0


if __name__ == "__main__":
    sys.exit(main())
