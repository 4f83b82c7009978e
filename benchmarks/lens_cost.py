"""What a lens costs per view: the same samples made with ``lens_model: none`` and with each lens model,
interleaved in one process. ``python -m benchmarks.lens_cost [--config P] [--size HxW] [--samples N]``
from the repository root.

Each sample is made by ``sample.render_arrays`` (the renderer, with a lens its resampling pass, the
homographies; same seeds and indices, so the same scenes: the lens draws change no other draw), after 3
warm-up samples per model; torch runs one thread. Prints per model the median ms per view in wall-clock
and this process's CPU time, the ratio of the CPU medians to ``none``, the ``"lens"`` step's share (the
canvas windows and Newton steps, and the renderer's resampling pass) and the mean canvas window a view is
drawn over (``sample.lens_views.lens_canvas``), in pixels and as a ratio to the output's, then the
machine's load. Numbers only.

    python -m benchmarks.lens_cost --size 384x512 --samples 12
"""

from __future__ import annotations

import argparse

from sidar_torch import SidarDataset
from sidar_torch.sample.lens_views import lens_canvas
from sidar_torch.sample import render_arrays
from sidar_torch.scene import sample_sequence
from sidar_torch.timing import collect_timings

from .common import machine, machine_line, median, one_thread
from .paired import CLOCKS, WARMUP, paired_config, paired_parser

MODELS = ("none", "brown_conrady", "division")


def _sample_ms(dataset: SidarDataset, index: int) -> dict[str, float]:
    """Make sample ``index`` of ``dataset``; ms per view by clock (``CLOCKS``); its steps go to the open
    ``sidar_torch.timing.collect_timings``."""
    rng = dataset.generator(index)
    sequence = sample_sequence(dataset.config, rng)
    painting = dataset.source.painting(index % len(dataset.source), dataset.config.image_size)
    start = {clock: read() for clock, read in CLOCKS.items()}
    render_arrays(dataset.renderer(), sequence, painting, dataset.config, index, rng=rng)
    return {clock: 1e3 * (read() - start[clock]) / len(sequence.views) for clock, read in CLOCKS.items()}


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``python -m benchmarks.lens_cost``; parsing it runs nothing."""
    return paired_parser("lens_cost", __doc__.splitlines()[0], samples=12, set_example="lens_k1=[-0.1,0]")


def main(argv: list[str] | None = None) -> None:
    args = build_parser().parse_args(argv)
    config = paired_config("lens_cost", args)
    datasets = {model: SidarDataset(config=config.replace(lens_model=model), seed=0) for model in MODELS}
    before = machine()
    ms: dict[str, dict[str, list[float]]] = {model: {clock: [] for clock in CLOCKS} for model in MODELS}
    steps: dict[str, dict[str, float]] = {model: {} for model in MODELS}
    with one_thread():
        for index in [10_000 + k for k in range(WARMUP)] + list(range(args.samples)):
            order = MODELS if index % 2 else MODELS[::-1]
            for model in order:
                with collect_timings() as timings:
                    times = _sample_ms(datasets[model], index)
                if index >= 10_000:
                    continue
                for clock, value in times.items():
                    ms[model][clock].append(value)
                for step, seconds in timings.items():
                    steps[model][step] = steps[model].get(step, 0.0) + seconds
    base = median(ms["none"]["cpu"])
    print(f"{args.config} at {args.size[0]}x{args.size[1]}, {config.n_views} views, {args.samples} samples per model")
    print("| lens_model | wall ms / view | cpu ms / view | cpu ratio to none | lens step share | canvas px / view "
          "| canvas / output |")
    print("|---|---|---|---|---|---|---|")
    output = args.size[0] * args.size[1]
    for model in MODELS:
        total = sum(steps[model].values())
        share = steps[model].get("lens", 0.0) / total if total else 0.0
        pixels = _canvas_pixels(datasets[model], args.samples)
        print(f"| {model} | {median(ms[model]['wall']):.1f} | {median(ms[model]['cpu']):.1f} | "
              f"{median(ms[model]['cpu']) / base:.2f} | {100 * share:.0f} % | {pixels:.0f} | {pixels / output:.2f} |")
    print(machine_line(before, machine()))


def _canvas_pixels(dataset: SidarDataset, samples: int) -> float:
    """Mean pixels of the canvas window each view of ``samples`` samples of ``dataset`` is drawn over (the
    output's without a lens)."""
    from sidar_torch.render.resample import LensResampling  # imports PyOpenGL: here, so parsing loads no GL

    pixels: list[int] = []
    for index in range(samples):
        sequence = dataset.scene(index)
        size = sequence.image_size
        if sequence.lens_model == "none":
            pixels += [size[0] * size[1]] * len(sequence.views)
            continue
        canvas = lens_canvas(LensResampling.of(sequence).border)
        pixels += [int(h) * int(w) for h, w in canvas.sizes]
    return sum(pixels) / len(pixels)


if __name__ == "__main__":
    main()
