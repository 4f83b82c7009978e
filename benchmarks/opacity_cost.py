"""Cost of the opacity draw: median time per view with and without ``opacity_output``, same run.
``python -m benchmarks.opacity_cost [--size HxW] [--samples N]`` from the repository root.

Renders the same scenes and paintings both ways, alternating which goes first, in this process's
shared renderers (one per setting), after warm-up samples (shader variants compile at first use). Prints, per view
(a sequence's ``SceneRenderer.render`` time over its views), the medians with and without, the
median paired difference (same sequence, with minus without; steadier on a loaded machine), in
wall-clock and in this process's CPU time (llvmpipe draws in this thread with
``LP_NUM_THREADS=0``, so CPU time is what other jobs on the machine disturb least), and the
median time of the opacity draw itself (its ``"opacity"`` step; swapping materials is ``"graph"``).

    python -m benchmarks.opacity_cost --config misaligned --size 384x512 --samples 60
"""

from __future__ import annotations

import argparse
import statistics
import time
from dataclasses import replace

from sidar_torch import SidarDataset, load_config
from sidar_torch.render import RenderSettings, shared_renderer

from .common import DEFAULT_PRESET, parse_size, size_label

CLOCKS = {"wall": time.perf_counter, "cpu": time.process_time}


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.opacity_cost", description=__doc__.splitlines()[0])
    parser.add_argument("--config", default=DEFAULT_PRESET, help=f"preset name or YAML path (default {DEFAULT_PRESET})")
    parser.add_argument("--size", type=parse_size, default=(384, 512), metavar="HxW", help="image size (default 384x512)")
    parser.add_argument("--samples", type=int, default=60, help="measured sequences (after 3 warm-up ones)")
    args = parser.parse_args(argv)
    config = load_config(args.config, image_size=args.size)
    dataset = SidarDataset(config=config, seed=0)
    settings = RenderSettings.from_config(config)
    renderers = {on: shared_renderer(replace(settings, opacities=on)) for on in (False, True)}
    ms_per_view = {(clock, on): [] for clock in CLOCKS for on in (False, True)}
    draw_ms: list[float] = []
    warmup = [10_000 + k for k in range(3)]
    for index in warmup + list(range(args.samples)):
        sequence = dataset.scene(index)
        painting = dataset.source.painting(index % len(dataset.source), config.image_size)
        for on in ((False, True) if index % 2 else (True, False)):
            timings: dict[str, float] = {}
            start = {clock: read() for clock, read in CLOCKS.items()}
            renderers[on].render(sequence, painting, timings)
            if index in warmup:
                continue
            for clock, read in CLOCKS.items():
                ms_per_view[clock, on].append(1e3 * (read() - start[clock]) / len(sequence.views))
            if on:
                draw_ms.append(1e3 * timings.get("opacity", 0.0) / len(sequence.views))
    print(f"{args.config} {size_label(args.size)} (H x W), {args.samples} sequences x {config.n_views} views")
    for clock in CLOCKS:
        without, with_ = (statistics.median(ms_per_view[clock, on]) for on in (False, True))
        paired = statistics.median(b - a for a, b in zip(ms_per_view[clock, False], ms_per_view[clock, True]))
        print(f"{clock:>4}: median ms / view without {without:.1f}, with {with_:.1f}; "
              f"median paired difference {paired:+.2f} ms ({100 * paired / without:+.1f} %)")
    print(f"opacity draw (wall): median {statistics.median(draw_ms):.2f} ms / view "
          f"(views without a visible occluder skip it)")


if __name__ == "__main__":
    main()
