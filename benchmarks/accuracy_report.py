"""The accuracy report: ``python -m benchmarks.accuracy_report [--quick]`` from the repository root.

Runs the measurements of :mod:`benchmarks.metrics` on fresh samples and prints one table:

* geometric residual of the warp ``H[i, j]`` (pixels) and its photometric error, on ambient,
  occluder-free scenes of :func:`~benchmarks.metrics.speckle_paintings` at several output sizes;
* homography error against the analytic plane-induced homographies over many random scenes of
  the default preset, in float64 and in the float32 handed out;
* label PSNR against the painting.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np
import torch

from sidar_torch.config import load_config
from sidar_torch.data.dataset import SidarDataset
from .metrics import homography_errors, psnr, speckle_paintings, warp_residuals
from sidar_torch.scene import sample_sequence

from .common import DEFAULT_PRESET, one_thread, parse_set, size_label

__all__ = ["AccuracySettings", "build_parser", "format_report", "main", "run_report"]


@dataclass(frozen=True)
class AccuracySettings:
    """What the report measures.

    Attributes:
        sizes: output sizes ``(H, W)`` for the warp residual and the label.
        samples: samples per size (each gives ``n_views * (n_views - 1)`` ordered pairs).
        n_views: views per sample.
        scenes: random scenes of the ``preset`` for the homography error.
        preset: the configuration whose cameras the homography sweep draws.
        seed: seed of every dataset and sweep.
        overrides: config fields applied to every configuration the report loads (the residual's
            ambient scenes, the homography sweep's ``preset`` and the label's); ``image_size`` and
            ``n_views`` come from ``sizes`` and ``n_views``.
    """

    sizes: tuple[tuple[int, int], ...] = ((131, 257), (192, 256), (384, 512), (768, 1024))
    samples: int = 8
    n_views: int = 4
    scenes: int = 100_000
    preset: str = DEFAULT_PRESET
    seed: int = 0
    overrides: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        reserved = {"image_size", "n_views"} & set(self.overrides)
        if reserved:
            raise ValueError(f"overrides: {sorted(reserved)} come from sizes and n_views; leave them out")
        for preset in ("ambient", self.preset, "misaligned"):  # fail before measuring anything
            load_config(preset, **self.overrides)

    @classmethod
    def quick(cls, **changes: Any) -> "AccuracySettings":
        """About a minute: two small sizes, 3 samples each, 2,000 scenes."""
        return cls(**{"sizes": ((131, 257), (192, 256)), "samples": 3, "scenes": 2000, **changes})


def alignment_row(size: tuple[int, int], samples: int, n_views: int, seed: int,
                  overrides: dict[str, Any] | None = None) -> dict[str, Any]:
    """Warp residuals of ``samples`` ambient, occluder-free samples at ``size`` (one table row)."""
    config = load_config("ambient", **(overrides or {}), image_size=size, n_views=n_views)
    dataset = SidarDataset(speckle_paintings(samples, size, seed), config, seed=seed)
    lengths, maes, pairs = [], [], 0
    for index in range(samples):
        s = dataset.sample(index)
        for pair in warp_residuals(s["images"], s["masks"], s["homographies"]):
            if len(pair.displacements):
                pairs += 1
                lengths.append(np.linalg.norm(pair.displacements, axis=1))
                maes.append(pair.photometric_mae)
    if not lengths:
        raise ValueError(f"size {size}: no view pair had a textured patch seen by both views; use a larger size")
    lengths = np.concatenate(lengths)
    return {"size": size_label(size), "pairs": pairs, "patches": len(lengths),
            "median_px": float(np.median(lengths)), "p99_px": float(np.percentile(lengths, 99)),
            "max_px": float(lengths.max()), "photometric_mae_levels": 255 * float(np.mean(maes))}


def homography_row(preset: str, scenes: int, seed: int, progress: Callable[[int], None] | None = None,
                   overrides: dict[str, Any] | None = None) -> dict[str, Any]:
    """Largest homography errors over ``scenes`` random scenes of ``preset`` (with ``overrides``)."""
    config = load_config(preset, **(overrides or {}))
    worst = {"float64_px": 0.0, "float32_px": 0.0, "cycle32": 0.0}
    for index in range(scenes):
        e = homography_errors(sample_sequence(config, np.random.default_rng([seed, index])))
        worst = {"float64_px": max(worst["float64_px"], e.float64), "float32_px": max(worst["float32_px"], e.float32),
                 "cycle32": max(worst["cycle32"], e.cycle32)}
        if progress is not None:
            progress(index + 1)
    return {"preset": preset, "scenes": scenes, "views": config.n_views, **worst}


def label_row(size: tuple[int, int], samples: int, seed: int, overrides: dict[str, Any] | None = None) -> dict[str, Any]:
    """PSNR of the label against the (fitted) procedural painting, worst of ``samples``."""
    config = load_config("misaligned", **(overrides or {}), image_size=size, n_views=1)
    dataset = SidarDataset(None, config, seed=seed)
    values = []
    for index in range(samples):
        painting = dataset.source.painting(index, size)
        label = dataset.sample(index)["label"]
        values.append(psnr(label, torch.from_numpy(painting).permute(2, 0, 1).float() / 255))
    return {"size": size_label(size), "samples": samples, "min_psnr_db": min(values)}


def run_report(settings: AccuracySettings, log: Callable[[str], None] = print) -> dict[str, Any]:
    """Every measurement of the report, as plain data (see :func:`format_report`)."""
    start = time.perf_counter()
    alignment = []
    for size in settings.sizes:
        alignment.append(alignment_row(size, settings.samples, settings.n_views, settings.seed, settings.overrides))
        log(f"warp residual at {size_label(size)}: done ({time.perf_counter() - start:.0f} s)")
    step = max(settings.scenes // 10, 1)

    def progress(done: int) -> None:
        if done % step == 0:
            log(f"homography sweep: {done}/{settings.scenes} scenes ({time.perf_counter() - start:.0f} s)")

    homography = homography_row(settings.preset, settings.scenes, settings.seed, progress, settings.overrides)
    labels = [label_row(size, settings.samples, settings.seed, settings.overrides) for size in settings.sizes]
    return {"alignment": alignment, "homography": homography, "label": labels,
            "seconds": time.perf_counter() - start}


def format_report(report: dict[str, Any]) -> str:
    """The report as markdown tables, with the accuracy targets beside the figures."""
    lines = ["Warp residual: view i warped by H[i, j] against view j (ambient, no occluders, speckle paintings)",
             "", "| size (H x W) | pairs | patches | median px | p99 px | max px | photometric MAE (levels) |",
             "|---|---|---|---|---|---|---|"]
    for r in report["alignment"]:
        lines.append(f"| {r['size']} | {r['pairs']} | {r['patches']} | {r['median_px']:.4f} | {r['p99_px']:.4f} "
                     f"| {r['max_px']:.4f} | {r['photometric_mae_levels']:.2f} |")
    lines += ["", "Target: median <= 0.05 px, max <= 0.2 px.", ""]
    h = report["homography"]
    lines += [f"Homography error over {h['scenes']} scenes of '{h['preset']}' ({h['views']} views), pixels of the "
              "target view at painting points both views see:", "",
              "| float64 (Kornia DLT vs analytic) | float32 handed out | max abs(H[i,j] H[j,i] - I), float32 |",
              "|---|---|---|",
              f"| {h['float64_px']:.2e} | {h['float32_px']:.2e} | {h['cycle32']:.2e} |",
              "", "Target: float64 <= 1e-6 px.", "",
              "| label size (H x W) | samples | worst label PSNR (dB) |", "|---|---|---|"]
    for r in report["label"]:
        value = "inf (identical)" if math.isinf(r["min_psnr_db"]) else f"{r['min_psnr_db']:.1f}"
        lines.append(f"| {r['size']} | {r['samples']} | {value} |")
    lines += ["", "Target: >= 45 dB.", "", f"Measured in {report['seconds']:.0f} s."]
    return "\n".join(lines)


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``python -m benchmarks.accuracy_report``; parsing it runs nothing."""
    parser = argparse.ArgumentParser(
        prog="python -m benchmarks.accuracy_report",
        description="Warp residual of H[i, j] on rendered views at 131x257 to 768x1024 (H x W), homography error "
                    "against the analytic plane-induced homographies over 100,000 scenes, label PSNR; prints a "
                    "table. About 45 minutes on 2 cores (the homography sweep); --quick about a minute.")
    parser.add_argument("--quick", action="store_true", help="two small sizes and 2,000 scenes (about a minute)")
    parser.add_argument("--scenes", type=int, default=None, help="scenes in the homography sweep")
    parser.add_argument("--config", default=DEFAULT_PRESET,
                        help=f"preset name or YAML path whose cameras the homography sweep draws (default {DEFAULT_PRESET})")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="override a config field of every configuration the report loads (repeatable), e.g. "
                             "--set fov_deg=[20,40]; image_size and n_views come from the report's sizes")
    parser.add_argument("--json", default=None, help="also write the figures as JSON to this path")
    parser.add_argument("--markdown", default=None, help="also write the table as markdown to this path")
    return parser


def main(argv: list[str] | None = None) -> None:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.scenes is not None and args.scenes < 1:
        parser.error(f"--scenes {args.scenes}: expected at least 1")
    try:
        changes = {"preset": args.config, "overrides": parse_set(args.set),
                   **({"scenes": args.scenes} if args.scenes is not None else {})}
        settings = (AccuracySettings.quick if args.quick else AccuracySettings)(**changes)
    except (ValueError, FileNotFoundError) as error:
        raise SystemExit(f"accuracy_report: {error}") from error
    # One thread: the sweep is a long run of tiny tensor operations, which torch's thread pool
    # slows down (a batched 3 x 3 determinant took 16 ms with 2 threads, 15 us with 1).
    with one_thread():
        report = run_report(settings, log=lambda line: print(line, file=sys.stderr))
    text = format_report(report)
    print(text)
    if args.json:
        with open(args.json, "w") as out:
            json.dump(report, out, indent=2)
    if args.markdown:
        with open(args.markdown, "w") as out:
            out.write(text + "\n")


if __name__ == "__main__":
    main()
