"""Cost of the view effects (``sidar_torch.sample.effects``): draw + apply, per sample, on one core.
``python -m benchmarks.effects_cost [--size HxW] [--views V]`` from the repository root.

Renders ``--samples`` sequences of a preset once (``SidarDataset(config, seed=0).scene(i)``), then
times :func:`~sidar_torch.sample.effects.draw_effects` plus :func:`~sidar_torch.sample.effects.apply_effects`
on them with each effect switched on alone (the pixel filter at the ``paper_*`` presets' sigma) and
with the four drawn ones together, ``--repeats`` times each, and
prints the median milliseconds of process CPU time per sample next to the median render time of
the same samples. Torch runs one thread (as in ``benchmarks.bench``). Prints numbers only;
nothing is asserted.

    python -m benchmarks.effects_cost --size 384x512 --views 6
"""

from __future__ import annotations

import argparse

import numpy as np

from sidar_torch import SidarDataset, load_config
from sidar_torch.sample.effects import apply_effects, draw_effects
from sidar_torch.render import RenderSettings, shared_renderer

from .common import DEFAULT_PRESET, cpu_seconds, median, one_thread, parse_size, size_label

EFFECTS = {
    "background=view": {"background": "view"},
    "pixel_filter_sigma=0.85": {"pixel_filter_sigma": 0.85},
    "exposure_jitter": {"exposure_jitter": True},
    "sensor_noise": {"sensor_noise": True},
    "jpeg": {"jpeg": True},
    "all four": {"background": "view", "exposure_jitter": True, "sensor_noise": True, "jpeg": True},
}


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``python -m benchmarks.effects_cost``; parsing it runs nothing."""
    parser = argparse.ArgumentParser(prog="python -m benchmarks.effects_cost", description=__doc__.split("\n\n")[0])
    parser.add_argument("--config", default=DEFAULT_PRESET, help=f"preset name or YAML path (default {DEFAULT_PRESET})")
    parser.add_argument("--size", type=parse_size, default=(384, 512), metavar="HxW", help="image size (default 384x512)")
    parser.add_argument("--views", type=int, default=6, help="views per sequence (default 6)")
    parser.add_argument("--samples", type=int, default=3, help="rendered sequences (default 3)")
    parser.add_argument("--repeats", type=int, default=5, help="timed passes over them per effect (default 5)")
    return parser


def main(argv: list[str] | None = None) -> None:
    args = build_parser().parse_args(argv)
    with one_thread():
        measure(args)


def measure(args: argparse.Namespace) -> None:
    """Render the sequences once, then time the effects on them (see the module docstring)."""
    base = load_config(args.config, image_size=args.size, n_views=args.views)
    dataset = SidarDataset(None, base, seed=0)
    renderer = shared_renderer(RenderSettings.from_config(base))
    renderer.render(dataset.scene(args.samples), dataset.source.painting(args.samples, base.image_size))  # warm-up
    rendered, render_s = [], []
    for i in range(args.samples):
        sequence, painting = dataset.scene(i), dataset.source.painting(i, base.image_size)
        render_s.append(cpu_seconds(lambda: rendered.append(renderer.render(sequence, painting))))
    print(f"{args.config} {size_label(args.size)} (H x W), {args.views} views: render "
          f"{1e3 * median(render_s):.0f} ms CPU per sample")
    for name, fields in EFFECTS.items():
        config = base.replace(**fields)
        seconds = []
        for repeat in range(args.repeats):
            for i, out in enumerate(rendered):
                rng = np.random.default_rng([repeat, i])
                seconds.append(cpu_seconds(lambda: apply_effects(
                    out.views, out.background, draw_effects(config, args.views, config.image_size, rng))))
        print(f"  {name}: {1e3 * median(seconds):.1f} ms CPU per sample")


if __name__ == "__main__":
    main()
