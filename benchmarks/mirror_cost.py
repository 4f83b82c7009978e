"""Cost of the painting's reflections and refraction (``render.mirror``): median time per view with and
without them on the same scenes, same run. ``python -m benchmarks.mirror_cost [--config P] [--set K=V]``
from the repository root.

Renders each sequence with ``RenderSettings.mirrors`` off and on (``benchmarks.paired``) and prints,
per view, the medians and the median paired difference in wall-clock and this process's CPU time,
and the share of views that draw an occluder with a quirk-8 program variant (a reflective or glass
material): the other views run the same programs either way.

    python -m benchmarks.mirror_cost --config paper_misaligned --size 384x512 --samples 40
    python -m benchmarks.mirror_cost --set occluder_materials=[metallic,glass] --set n_occluders=[2,3]
"""

from __future__ import annotations

import argparse

from sidar_torch import SidarDataset

from .common import size_label
from .paired import paired_config, paired_parser, paired_view_times, print_paired


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``python -m benchmarks.mirror_cost``; parsing it runs nothing."""
    return paired_parser("mirror_cost", __doc__.splitlines()[0], samples=40, set_example="occluder_materials=[metallic,glass]")


def main(argv: list[str] | None = None) -> None:
    from sidar_torch.render.mirror import mirror_define  # imports pyrender: here, so build_parser() loads no GL

    args = build_parser().parse_args(argv)
    config = paired_config("mirror_cost", args)
    ms_per_view, _ = paired_view_times(config, "mirrors", args.samples)
    dataset = SidarDataset(config=config, seed=0)
    views = [v for i in range(args.samples) for v in dataset.scene(i).views]
    mirrored = sum(any(mirror_define(o.material) for o in v.occluders) for v in views)
    print(f"{args.config} {' '.join(args.set)} {size_label(args.size)} (H x W), {args.samples} sequences x "
          f"{config.n_views} views; {mirrored} of {len(views)} views have a reflective or glass occluder")
    print_paired(ms_per_view)


if __name__ == "__main__":
    main()
