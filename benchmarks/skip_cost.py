"""What a skip of work that cannot change a pixel saves: median time per view with one of the
renderer's skips (a ``RenderSettings`` switch, the pixels the same either way) off and on, on the
same scenes, same run. ``python -m benchmarks.skip_cost --skip NAME [--config P] [--set K=V]`` from
the repository root.

Renders each sequence with the switch off and on (``benchmarks.paired``) and prints what the skip
leaves out, then per view the medians and the median paired difference in wall-clock and this
process's CPU time. What is left out: for ``split_shadow_lookups`` (``render.footprints``), from the
plans alone (no GL), the share of the painting's shadow lookups the split keeps (weighted by the
painting pixels each part covers) and the draws per view; for ``clear_written_texels``
(``render.shadow_array``), the share of the shadow and transmittance maps' texels cleared.

    python -m benchmarks.skip_cost --skip split_shadow_lookups --config misaligned --size 384x512 --samples 40
    python -m benchmarks.skip_cost --skip clear_written_texels --config misaligned --size 384x512 --samples 40
"""

from __future__ import annotations

import argparse
import statistics

import numpy as np

from sidar_torch import SidarDataset

from .common import size_label
from .paired import paired_config, paired_parser, paired_view_times, print_paired


SKIPS = ("split_shadow_lookups", "clear_written_texels", "skip_idle_shadows", "cull_occluders", "reuse_shadow_maps",
         "masks_from_outline", "masks_from_stencil", "label_from_painting")
"""The ``RenderSettings`` switches of work that cannot change a pixel."""


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``python -m benchmarks.skip_cost``; parsing it runs nothing."""
    parser = paired_parser("skip_cost", __doc__.splitlines()[0], samples=40, set_example="n_occluders=[3,4]")
    parser.add_argument("--skip", choices=SKIPS, default="split_shadow_lookups", help="the skip measured")
    return parser


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


def cleared_texels(config) -> tuple[np.ndarray, np.ndarray]:
    """The depth and transmittance map texels that the renderers of ``config`` with
    ``clear_written_texels`` on and off have cleared so far in this process (shared renderers: other
    work in the process counts too, so take differences): ``(on, off)``, each ``[depth, transmittance]``."""
    from dataclasses import replace

    from sidar_torch.render import RenderSettings, shared_renderer

    settings = RenderSettings.from_config(config)
    on, off = (shared_renderer(replace(settings, clear_written_texels=flag))._passes for flag in (True, False))
    return tuple(np.array([gl.shadow_maps.cleared_texels, gl.transmittance.cleared_texels]) for gl in (on, off))


def main(argv: list[str] | None = None) -> None:
    args = build_parser().parse_args(argv)
    config = paired_config("skip_cost", args)
    before = cleared_texels(config) if args.skip == "clear_written_texels" else None
    ms_per_view, _ = paired_view_times(config, args.skip, args.samples)
    left_out = ""
    if args.skip == "split_shadow_lookups":
        share, draws = lookups_kept(config, args.samples)
        left_out = (f"; the split keeps {100 * share:.0f} % of the painting's shadow lookups, in {draws:g} draws "
                    f"per view (median)")
    elif args.skip == "clear_written_texels":
        (on, off), (on_before, off_before) = cleared_texels(config), before  # this run's clears only
        depth, tints = (on - on_before) / np.maximum(off - off_before, 1)
        left_out = (f"; {100 * depth:.0f} % of the depth maps' texels cleared, {100 * tints:.0f} % of the "
                    f"transmittance maps'")
    print(f"{args.skip}: {args.config} {' '.join(args.set)} {size_label(args.size)} (H x W), {args.samples} "
          f"sequences x {config.n_views} views{left_out}")
    print_paired(ms_per_view)


if __name__ == "__main__":
    main()
