"""Cost of the view effects (``sidar_torch.artifacts``): draw + apply, per sample, on one core.

Renders ``--samples`` sequences of a preset once (``SidarDataset(config, seed=0).scene(i)``), then
times :func:`~sidar_torch.artifacts.draw_effects` plus :func:`~sidar_torch.artifacts.apply_effects`
on them with each effect switched on alone and with all four, ``--repeats`` times each, and
prints the median milliseconds per sample next to the median render time of the same samples.
Torch runs one thread (as in ``bench``). Prints numbers only; nothing is asserted.

    .venv/bin/python scripts/effects_cost.py --size 384 512 --views 6
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np
import torch

from sidar_torch import SidarDataset, load_config
from sidar_torch.artifacts import apply_effects, draw_effects
from sidar_torch.render import RenderSettings, shared_renderer

EFFECTS = {
    "background=view": {"background": "view"},
    "exposure_jitter": {"exposure_jitter": True},
    "sensor_noise": {"sensor_noise": True},
    "jpeg": {"jpeg": True},
    "all four": {"background": "view", "exposure_jitter": True, "sensor_noise": True, "jpeg": True},
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--config", default="misaligned")
    parser.add_argument("--size", type=int, nargs=2, default=(384, 512), metavar=("H", "W"))
    parser.add_argument("--views", type=int, default=6)
    parser.add_argument("--samples", type=int, default=3)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    torch.set_num_threads(1)
    base = load_config(args.config, image_size=tuple(args.size), n_views=args.views)
    dataset = SidarDataset(None, base, seed=0)
    renderer = shared_renderer(RenderSettings.from_config(base))
    renderer.render(dataset.scene(args.samples), dataset.source.painting(args.samples, base.image_size))  # warm-up
    rendered, render_s = [], []
    for i in range(args.samples):
        sequence = dataset.scene(i)
        start = time.perf_counter()
        rendered.append((sequence, renderer.render(sequence, dataset.source.painting(i, base.image_size))))
        render_s.append(time.perf_counter() - start)
    print(f"{args.config} {args.size[0]}x{args.size[1]}, {args.views} views: render "
          f"{1e3 * statistics.median(render_s):.0f} ms per sample")
    for name, fields in EFFECTS.items():
        config = base.replace(**fields)
        seconds = []
        for repeat in range(args.repeats):
            for i, (sequence, out) in enumerate(rendered):
                start = time.perf_counter()
                effects = draw_effects(config, args.views, config.image_size, np.random.default_rng([repeat, i]))
                apply_effects(out.views, out.background, effects)
                seconds.append(time.perf_counter() - start)
        print(f"  {name}: {1e3 * statistics.median(seconds):.1f} ms per sample")


if __name__ == "__main__":
    main()
