"""Cost of the opacity draw: median time per view with and without ``opacity_output``, same run.

Renders the same scenes and paintings both ways, alternating which goes first, in this process's
shared renderer, after warm-up samples (shader variants compile at first use). Prints medians of
the per-view render time (a sequence's ``SceneRenderer.render`` time over its views) and of the
opacity draw itself (its ``"opacity"`` timing step, graph building included in ``"graph"``).

    .venv/bin/python scripts/opacity_cost.py --config misaligned --size 384 512 --samples 30
"""

from __future__ import annotations

import argparse
import statistics
import time

from sidar_torch import SidarDataset, load_config
from sidar_torch.render import shared_renderer


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", default="misaligned", help="preset name or YAML path")
    parser.add_argument("--size", type=int, nargs=2, default=(384, 512), metavar=("H", "W"))
    parser.add_argument("--samples", type=int, default=30, help="measured sequences (after 3 warm-up ones)")
    args = parser.parse_args()
    config = load_config(args.config, image_size=tuple(args.size))
    dataset = SidarDataset(config=config, seed=0)
    renderer = shared_renderer(config.image_size, config.shadow_map_size)
    per_view: dict[bool, list[float]] = {False: [], True: []}
    draw_ms: list[float] = []
    drawn = views = 0
    warmup = [10_000 + k for k in range(3)]
    for index in warmup + list(range(args.samples)):
        sequence = dataset.scene(index)
        painting = dataset.source.painting(index % len(dataset.source), config.image_size)
        for opacities in ((False, True) if index % 2 else (True, False)):
            timings: dict[str, float] = {}
            start = time.perf_counter()
            renderer.render(sequence, painting, timings, opacities=opacities)
            seconds = time.perf_counter() - start
            if index in warmup:
                continue
            per_view[opacities].append(1e3 * seconds / len(sequence.views))
            if opacities:
                draw_ms.append(1e3 * timings.get("opacity", 0.0) / len(sequence.views))
        if index not in warmup:
            views += len(sequence.views)
            drawn += sum(bool(v.occluders) and config.occluders_visible for v in sequence.views)
    without, with_ = statistics.median(per_view[False]), statistics.median(per_view[True])
    print(f"{args.config} {args.size[1]}x{args.size[0]}, {args.samples} sequences x {config.n_views} views")
    print(f"median ms / view without opacities: {without:.1f}")
    print(f"median ms / view with opacities:    {with_:.1f}  (+{with_ - without:.1f}, {100 * (with_ / without - 1):+.1f} %)")
    print(f"median ms / view in the opacity draw: {statistics.median(draw_ms):.2f} "
          f"(views with occluders in the scene: {drawn}/{views}; views without any visible skip the draw)")


if __name__ == "__main__":
    main()
