"""What shadow footprints save (``render.footprints``): median time per view with the painting's lit
draw split by footprints and with one draw doing every lookup, on the same scenes, same run.
``python -m benchmarks.footprint_cost [--config P] [--set K=V]`` from the repository root.

Renders each sequence with ``RenderSettings.split_shadow_lookups`` off and on (``benchmarks.paired``;
the pixels are the same either way) and prints, per view, the medians and the median paired
difference in wall-clock and this process's CPU time, then from the plans alone (no GL) the share
of the painting's shadow lookups the split keeps (weighted by the painting pixels each part covers)
and the draws per view.

    python -m benchmarks.footprint_cost --config misaligned --size 384x512 --samples 40
"""

from __future__ import annotations

import argparse
import statistics

from sidar_torch import SidarDataset

from .common import size_label
from .paired import paired_config, paired_parser, paired_view_times, print_paired


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``python -m benchmarks.footprint_cost``; parsing it runs nothing."""
    return paired_parser("footprint_cost", __doc__.splitlines()[0], samples=40, set_example="n_occluders=[3,4]")


def lookups_kept(config, samples: int) -> tuple[float, float]:
    """``(share of the painting's lookups kept, median draws per view with a split)`` over the
    first ``samples`` sequences' plans (views whose painting is drawn with shadow lookups)."""
    from sidar_torch.render import RenderSettings  # imports pyrender: here, so build_parser() loads no GL
    from sidar_torch.render.plan import plan_views
    from sidar_torch.render.visibility import painting_mask

    dataset, settings = SidarDataset(config=config, seed=0), RenderSettings.from_config(config)
    kept = full = 0
    draws = []
    for index in range(samples):
        sequence = dataset.scene(index)
        for view, plan in zip(sequence.views, plan_views(sequence, settings)):
            if not plan.n_shadowed:
                continue
            seen = ~painting_mask(view.camera.K, view.camera.R, view.camera.t, config.image_size)
            full += int(seen.sum()) * plan.n_shadowed
            parts = plan.painting_parts
            kept += (sum(int(seen[p.y:p.y + p.height, p.x:p.x + p.width].sum()) * (p.end - p.begin) for p in parts)
                     if parts else int(seen.sum()) * plan.n_shadowed)
            draws.append(max(1, len(parts)))
    return kept / max(full, 1), statistics.median(draws) if draws else 0.0


def main(argv: list[str] | None = None) -> None:
    args = build_parser().parse_args(argv)
    config = paired_config("footprint_cost", args)
    ms_per_view, _ = paired_view_times(config, "split_shadow_lookups", args.samples)
    share, draws = lookups_kept(config, args.samples)
    print(f"{args.config} {' '.join(args.set)} {size_label(args.size)} (H x W), {args.samples} sequences x "
          f"{config.n_views} views; the split keeps {100 * share:.0f} % of the painting's shadow lookups, "
          f"in {draws:g} draws per view (median)")
    print_paired(ms_per_view)


if __name__ == "__main__":
    main()
