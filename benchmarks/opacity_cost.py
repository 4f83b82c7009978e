"""Cost of the opacity draw: median time per view with and without ``opacity_output``, same run.
``python -m benchmarks.opacity_cost [--config P] [--set K=V] [--size HxW] [--samples N]`` from the repository root.

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

from .common import size_label
from .paired import paired_config, paired_parser, paired_view_times, print_paired


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``python -m benchmarks.opacity_cost``; parsing it runs nothing."""
    return paired_parser("opacity_cost", __doc__.splitlines()[0], samples=60, set_example="n_occluders=[1,2]")


def main(argv: list[str] | None = None) -> None:
    args = build_parser().parse_args(argv)
    config = paired_config("opacity_cost", args)
    ms_per_view, steps = paired_view_times(config, "opacities", args.samples)
    draw_ms = [1e3 * on.get("opacity", 0.0) / config.n_views for _, on in steps]
    print(f"{args.config} {' '.join(args.set)} {size_label(args.size)} (H x W), {args.samples} sequences x "
          f"{config.n_views} views")
    print_paired(ms_per_view)
    print(f"opacity draw (wall): median {statistics.median(draw_ms):.2f} ms / view "
          f"(views without a visible occluder skip it)")


if __name__ == "__main__":
    main()
