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

from sidar_torch import SidarDataset, load_config

from .common import DEFAULT_PRESET, parse_set, parse_size, size_label
from .paired import paired_view_times, print_paired


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``python -m benchmarks.mirror_cost``; parsing it runs nothing."""
    parser = argparse.ArgumentParser(prog="python -m benchmarks.mirror_cost", description=__doc__.splitlines()[0])
    parser.add_argument("--config", default=DEFAULT_PRESET, help=f"preset name or YAML path (default {DEFAULT_PRESET})")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="override a config field (repeatable), e.g. --set occluder_materials=[metallic,glass]")
    parser.add_argument("--size", type=parse_size, default=(384, 512), metavar="HxW", help="image size (default 384x512)")
    parser.add_argument("--samples", type=int, default=40, help="measured sequences (after 3 warm-up ones)")
    return parser


def main(argv: list[str] | None = None) -> None:
    from sidar_torch.render.mirror import mirror_define  # imports pyrender: here, so build_parser() loads no GL

    args = build_parser().parse_args(argv)
    try:
        config = load_config(args.config, image_size=args.size, **parse_set(args.set))
    except (ValueError, FileNotFoundError) as error:
        raise SystemExit(f"mirror_cost: {error}") from error
    ms_per_view, _ = paired_view_times(config, "mirrors", args.samples)
    dataset = SidarDataset(config=config, seed=0)
    views = [v for i in range(args.samples) for v in dataset.scene(i).views]
    mirrored = sum(any(mirror_define(o.material) for o in v.occluders) for v in views)
    print(f"{args.config} {' '.join(args.set)} {size_label(args.size)} (H x W), {args.samples} sequences x "
          f"{config.n_views} views; {mirrored} of {len(views)} views have a reflective or glass occluder")
    print_paired(ms_per_view)


if __name__ == "__main__":
    main()
