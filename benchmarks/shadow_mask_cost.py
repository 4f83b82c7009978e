"""Cost of the shadow masks (``shadow_mask_output``): median time per view with and without them on the
same scenes, same run. ``python -m benchmarks.shadow_mask_cost [--config P] [--set K=V]`` from the
repository root.

Renders each sequence with ``RenderSettings.shadow_masks`` off and on (``benchmarks.paired``) and
prints, per view, the medians and the median paired difference in wall-clock and this process's CPU
time, then the median time of the shadow-mask draw itself (its ``"shadow_mask"`` step; views without
a shadowed light skip it).

    python -m benchmarks.shadow_mask_cost --config misaligned --size 384x512 --samples 40
"""

from __future__ import annotations

import argparse
import statistics

from .common import size_label
from .paired import paired_config, paired_parser, paired_view_times, print_paired


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``python -m benchmarks.shadow_mask_cost``; parsing it runs nothing."""
    return paired_parser("shadow_mask_cost", __doc__.splitlines()[0], samples=40, set_example="n_occluders=[1,3]")


def main(argv: list[str] | None = None) -> None:
    args = build_parser().parse_args(argv)
    config = paired_config("shadow_mask_cost", args)
    ms_per_view, steps = paired_view_times(config, "shadow_masks", args.samples)
    draw_ms = [1e3 * on.get("shadow_mask", 0.0) / config.n_views for _, on in steps]
    print(f"{args.config} {' '.join(args.set)} {size_label(args.size)} (H x W), {args.samples} sequences x "
          f"{config.n_views} views")
    print_paired(ms_per_view)
    print(f"shadow-mask draw (wall): median {statistics.median(draw_ms):.2f} ms / view "
          f"(views without a shadowed light skip it)")


if __name__ == "__main__":
    main()
