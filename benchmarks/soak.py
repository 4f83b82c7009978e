"""Soak test: render many samples in one process and watch memory and GL objects.
``python -m benchmarks.soak [--samples N] [--size HxW]`` from the repository root.

Renders ``SidarDataset(config=<preset at --size>, seed=--seed).sample(i)`` for ``i = 0..N-1``
(the built-in procedural source, so every sample has a new painting and new lights, occluders
and cameras) and prints, every ``--every`` samples, the resident memory, the shader programs of
the renderer, and the GL textures and buffers alive in its context. Memory growth is measured
from the end of the warm-up (``--warmup`` samples, by which time every shader variant has been
compiled and the allocators have reached their working size) to the last sample.

The renderer pools meshes (per occluder shape and count) and spot lights with their shadow
maps, so GL buffer and texture counts may rise after the warm-up while a rare scene (three
cubes in one view) first occurs; with ``--distinct D`` (``D <= --warmup``) the samples cycle
through indices ``0..D-1`` (still a new painting and scene for every sample of a cycle), every
pool is full after the warm-up, and those counts must stay exactly constant.

The last line of output is a JSON summary (``growth_mb``, ``max_growth_mb``, ``changed``, and
per report ``rss_mb``, ``programs``, ``gl_textures``, ``gl_buffers``). The exit code is 1 if
memory grew by more than ``--max-growth-mb`` after the warm-up, or the program count changed
after it, or (with ``--distinct``) the texture or buffer count did; else 0.

    python -m benchmarks.soak --samples 10000 --size 96x128 --every 500

Linux only (reads ``/proc/self/statm``).
"""

from __future__ import annotations

import argparse
import json
import sys
import time

from sidar_torch import SidarDataset, load_config  # first: it selects the GL platform
from sidar_torch.render import RenderSettings, shared_renderer

from .common import DEFAULT_PRESET, parse_size, rss_mb, size_label

NAME_WINDOW = 1024
"""GL names scanned above the next free one (see :func:`count_gl_names`)."""


def count_gl_names(is_name, gen_names, delete_names) -> int:
    """Number of live objects of one GL kind (textures, buffers) in the current context.

    GL has no "how many" query, so names are tested one by one with ``glIs*``: from 1 to
    ``NAME_WINDOW`` past the name ``glGen*`` hands out next. Mesa hands out the lowest free
    name, or the next unused one, so live names above that probe are few and near it.
    """
    probe = int(gen_names(1))
    delete_names(1, [probe])
    return sum(bool(is_name(name)) for name in range(1, probe + NAME_WINDOW))


def report(samples: int, renderer, started: float) -> dict:
    """One report line's figures; the renderer's context must be current (it is after a render)."""
    from OpenGL import GL  # here, not at import: reading the command line loads no GL

    return {
        "samples": samples,
        "rss_mb": round(rss_mb(), 1),
        "programs": renderer.program_count,
        "gl_textures": count_gl_names(GL.glIsTexture, GL.glGenTextures, GL.glDeleteTextures),
        "gl_buffers": count_gl_names(GL.glIsBuffer, GL.glGenBuffers, GL.glDeleteBuffers),
        "seconds": round(time.perf_counter() - started, 1),
    }


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``python -m benchmarks.soak``; parsing it runs nothing."""
    parser = argparse.ArgumentParser(prog="python -m benchmarks.soak", description=__doc__.split("\n\n")[0])
    parser.add_argument("--samples", type=int, default=10_000, help="samples to render (default 10000)")
    parser.add_argument("--size", type=parse_size, default=(384, 512), metavar="HxW",
                        help="image size, height x width in pixels (default 384x512)")
    parser.add_argument("--config", default=DEFAULT_PRESET, help=f"preset name or YAML path (default {DEFAULT_PRESET})")
    parser.add_argument("--seed", type=int, default=0, help="dataset seed (default 0)")
    parser.add_argument("--every", type=int, default=500, help="report every N samples (default 500)")
    parser.add_argument("--warmup", type=int, default=None,
                        help="samples before the memory baseline (default: one report interval)")
    parser.add_argument("--distinct", type=int, default=None,
                        help="cycle through this many sample indices, at most --warmup (default: all new)")
    parser.add_argument("--max-growth-mb", type=float, default=50.0,
                        help="largest allowed growth after the warm-up, MiB (default 50)")
    return parser


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    """The options of ``argv``, checked against each other (``--every``, ``--warmup``, ``--samples``,
    ``--distinct``); a mistake exits as argparse does (code 2, one line)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    args.warmup = args.every if args.warmup is None else args.warmup
    if args.every < 1 or args.warmup < 1:
        parser.error("--every and --warmup must be >= 1")
    if args.samples <= args.warmup or (args.samples - args.warmup) % args.every or args.warmup % args.every:
        parser.error("--warmup and --samples must be multiples of --every, with --samples > --warmup")
    if args.distinct is not None and not 1 <= args.distinct <= args.warmup:
        parser.error("--distinct must be between 1 and --warmup")
    return args


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    dataset = SidarDataset(config=load_config(args.config, image_size=args.size), seed=args.seed)
    config = dataset.config
    print(f"soak: {args.samples} samples of {args.config!r} at {size_label(config.image_size)} (H x W), "
          f"{config.n_views} views, seed {args.seed}; warm-up {args.warmup}", flush=True)
    print(f"{'samples':>8} {'rss_mb':>8} {'programs':>8} {'gl_textures':>11} {'gl_buffers':>10} {'seconds':>8}")
    started = time.perf_counter()
    reports = []
    for done in range(1, args.samples + 1):
        dataset.sample((done - 1) % (args.distinct or args.samples))
        if done % args.every == 0:
            renderer = shared_renderer(RenderSettings.from_config(config))
            reports.append(report(done, renderer, started))
            r = reports[-1]
            print(f"{r['samples']:>8} {r['rss_mb']:>8.1f} {r['programs']:>8} {r['gl_textures']:>11} "
                  f"{r['gl_buffers']:>10} {r['seconds']:>8.1f}", flush=True)
    after = [r for r in reports if r["samples"] >= args.warmup]
    base = after[0]
    growth = after[-1]["rss_mb"] - base["rss_mb"]
    max_growth = max(r["rss_mb"] for r in after) - base["rss_mb"]
    changed = [key for key in ("programs", "gl_textures", "gl_buffers") if len({r[key] for r in after}) > 1]
    failed = [key for key in changed if key == "programs" or args.distinct]
    print(f"growth after warm-up: {growth:+.1f} MiB over {after[-1]['samples'] - base['samples']} samples "
          f"(largest {max_growth:+.1f} MiB; limit {args.max_growth_mb:g} MiB); "
          f"{(after[-1]['seconds'] - base['seconds']) / (after[-1]['samples'] - base['samples']) * 1000:.1f} ms/sample; "
          f"changed after warm-up: {', '.join(changed) or 'nothing'}")
    print(json.dumps({"growth_mb": round(growth, 1), "max_growth_mb": round(max_growth, 1), "warmup": args.warmup,
                      "changed": changed, "reports": reports}))
    return 1 if growth > args.max_growth_mb or failed else 0


if __name__ == "__main__":
    sys.exit(main())
