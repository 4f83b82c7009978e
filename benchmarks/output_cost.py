"""Cost of a drawn optional output (``shadow_mask_output``, ``shadow_free_output``, ``depth_output``): median
time per view with and without it on the same scenes, same run. ``python -m benchmarks.output_cost
[--output shadow_masks|shadow_free|depth] [--config P] [--set K=V]`` from the repository root.

Renders each sequence with the output's ``RenderSettings`` field off and on (``benchmarks.paired``)
and prints, per view, the medians and the median paired difference in wall-clock and this process's
CPU time, then the median paired difference of the steps the output adds to (the shadow mask's own
draw; the shadow-free view's second output of the colour draw and its readback; the depth's own draw
and its readback).

    python -m benchmarks.output_cost --output shadow_masks --config misaligned --size 384x512 --samples 40
    python -m benchmarks.output_cost --output shadow_free --config misaligned --size 384x512 --samples 40
    python -m benchmarks.output_cost --output depth --config parallax --size 384x512 --samples 40
"""

from __future__ import annotations

import argparse
import statistics

from .common import size_label
from .paired import paired_config, paired_parser, paired_view_times, print_paired

OUTPUTS = {"shadow_masks": ("shadow_mask",), "shadow_free": ("colour", "readback"), "depth": ("depth", "readback")}
"""``RenderSettings`` field of each output -> the steps its work is timed under (``SceneRenderer.render``)."""


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``python -m benchmarks.output_cost``; parsing it runs nothing."""
    parser = paired_parser("output_cost", __doc__.splitlines()[0], samples=40, set_example="n_occluders=[1,3]")
    parser.add_argument("--output", choices=sorted(OUTPUTS), default="shadow_masks", help="the output measured")
    return parser


def main(argv: list[str] | None = None) -> None:
    args = build_parser().parse_args(argv)
    config = paired_config("output_cost", args)
    ms_per_view, steps = paired_view_times(config, args.output, args.samples)
    names = OUTPUTS[args.output]
    step_ms = [1e3 * sum(on.get(n, 0.0) - off.get(n, 0.0) for n in names) / config.n_views for off, on in steps]
    print(f"{args.output}: {args.config} {' '.join(args.set)} {size_label(args.size)} (H x W), {args.samples} "
          f"sequences x {config.n_views} views")
    print_paired(ms_per_view)
    print(f"{' + '.join(names)} (wall): median paired difference {statistics.median(step_ms):+.2f} ms / view "
          + ("" if args.output == "depth" else "(views without a shadowed light add nothing)"))


if __name__ == "__main__":
    main()
