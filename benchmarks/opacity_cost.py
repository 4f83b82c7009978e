"""Cost of the opacity draw: median time per view with and without ``opacity_output``, same run.
``python -m benchmarks.opacity_cost [--size HxW] [--samples N]`` from the repository root.

Renders the same scenes and paintings both ways, alternating which goes first, in this process's
shared renderers (one per setting), after warm-up samples (shader variants compile at first use). Prints, per view
(a sequence's ``SceneRenderer.render`` time over its views), the medians with and without, the
median paired difference (same sequence, with minus without; steadier on a loaded machine), in
wall-clock and in this process's CPU time (llvmpipe draws in this thread with
``LP_NUM_THREADS=0``, so CPU time is what other jobs on the machine disturb least), and the
median time of the opacity draw itself (its ``"opacity"`` step; swapping materials is ``"graph"``).

    python -m benchmarks.opacity_cost --config misaligned --size 384x512 --samples 60
"""

from __future__ import annotations

import argparse
import statistics

from sidar_torch import load_config

from .common import DEFAULT_PRESET, parse_size, size_label
from .paired import paired_view_times, print_paired


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``python -m benchmarks.opacity_cost``; parsing it runs nothing."""
    parser = argparse.ArgumentParser(prog="python -m benchmarks.opacity_cost", description=__doc__.splitlines()[0])
    parser.add_argument("--config", default=DEFAULT_PRESET, help=f"preset name or YAML path (default {DEFAULT_PRESET})")
    parser.add_argument("--size", type=parse_size, default=(384, 512), metavar="HxW", help="image size (default 384x512)")
    parser.add_argument("--samples", type=int, default=60, help="measured sequences (after 3 warm-up ones)")
    return parser


def main(argv: list[str] | None = None) -> None:
    args = build_parser().parse_args(argv)
    config = load_config(args.config, image_size=args.size)
    ms_per_view, steps = paired_view_times(config, "opacities", args.samples)
    draw_ms = [1e3 * on.get("opacity", 0.0) / config.n_views for _, on in steps]
    print(f"{args.config} {size_label(args.size)} (H x W), {args.samples} sequences x {config.n_views} views")
    print_paired(ms_per_view)
    print(f"opacity draw (wall): median {statistics.median(draw_ms):.2f} ms / view "
          f"(views without a visible occluder skip it)")


if __name__ == "__main__":
    main()
