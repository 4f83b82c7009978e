"""Cost of the shadow outputs (``shadow_mask_output``, ``shadow_free_output``): median time per view
with and without one of them on the same scenes, same run. ``python -m benchmarks.shadow_outputs_cost
[--output shadow_masks|shadow_free] [--config P] [--set K=V]`` from the repository root.

Renders each sequence with the output's ``RenderSettings`` field off and on (``benchmarks.paired``)
and prints, per view, the medians and the median paired difference in wall-clock and this process's
CPU time, then the median time of the output's own draw (its step; views without a shadowed light
skip it).

    python -m benchmarks.shadow_outputs_cost --output shadow_masks --config misaligned --size 384x512 --samples 40
    python -m benchmarks.shadow_outputs_cost --output shadow_free --config misaligned --size 384x512 --samples 40
"""

from __future__ import annotations

import argparse
import statistics

from .common import size_label
from .paired import paired_config, paired_parser, paired_view_times, print_paired

OUTPUTS = {"shadow_masks": "shadow_mask", "shadow_free": "shadow_free"}
"""``RenderSettings`` field of each output -> the step its draw is timed under."""


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``python -m benchmarks.shadow_outputs_cost``; parsing it runs nothing."""
    parser = paired_parser("shadow_outputs_cost", __doc__.splitlines()[0], samples=40, set_example="n_occluders=[1,3]")
    parser.add_argument("--output", choices=sorted(OUTPUTS), default="shadow_masks", help="the output measured")
    return parser


def main(argv: list[str] | None = None) -> None:
    args = build_parser().parse_args(argv)
    config = paired_config("shadow_outputs_cost", args)
    ms_per_view, steps = paired_view_times(config, args.output, args.samples)
    draw_ms = [1e3 * on.get(OUTPUTS[args.output], 0.0) / config.n_views for _, on in steps]
    print(f"{args.output}: {args.config} {' '.join(args.set)} {size_label(args.size)} (H x W), {args.samples} "
          f"sequences x {config.n_views} views")
    print_paired(ms_per_view)
    print(f"{args.output} draw (wall): median {statistics.median(draw_ms):.2f} ms / view "
          f"(views without a shadowed light skip it)")


if __name__ == "__main__":
    main()
