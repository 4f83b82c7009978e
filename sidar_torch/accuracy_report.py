"""The accuracy report: ``python -m sidar_torch accuracy [--quick]``.

Runs the measurements of :mod:`sidar_torch.accuracy` on fresh samples and prints one table:

* geometric residual of the warp ``H[i, j]`` (pixels) and its photometric error, on ambient,
  occluder-free scenes of :func:`~sidar_torch.accuracy.speckle_paintings` at several output sizes;
* homography error against the analytic plane-induced homographies over many random scenes of
  the default preset, in float64 and in the float32 handed out;
* label PSNR against the painting.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np
import torch

from .accuracy import homography_errors, psnr, speckle_paintings, warp_residuals
from .config import load_config
from .dataset import SidarDataset
from .scene import sample_sequence

__all__ = ["AccuracySettings", "run_report", "format_report"]


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
    preset: str = "misaligned"
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
    return {"size": f"{size[1]}x{size[0]}", "pairs": pairs, "patches": len(lengths),
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
    return {"size": f"{size[1]}x{size[0]}", "samples": samples, "min_psnr_db": min(values)}


def run_report(settings: AccuracySettings, log: Callable[[str], None] = print) -> dict[str, Any]:
    """Every measurement of the report, as plain data (see :func:`format_report`)."""
    start = time.perf_counter()
    alignment = []
    for size in settings.sizes:
        alignment.append(alignment_row(size, settings.samples, settings.n_views, settings.seed, settings.overrides))
        log(f"warp residual at {size[1]}x{size[0]}: done ({time.perf_counter() - start:.0f} s)")
    step = max(settings.scenes // 10, 1)

    def progress(done: int) -> None:
        if done % step == 0:
            log(f"homography sweep: {done}/{settings.scenes} scenes ({time.perf_counter() - start:.0f} s)")

    homography = homography_row(settings.preset, settings.scenes, settings.seed, progress, settings.overrides)
    labels = [label_row(size, settings.samples, settings.seed, settings.overrides) for size in settings.sizes]
    return {"alignment": alignment, "homography": homography, "label": labels,
            "seconds": time.perf_counter() - start}


def format_report(report: dict[str, Any]) -> str:
    """The report as markdown tables, with the targets of the accuracy issue beside the figures."""
    lines = ["Warp residual: view i warped by H[i, j] against view j (ambient, no occluders, speckle paintings)",
             "", "| size | pairs | patches | median px | p99 px | max px | photometric MAE (levels) |",
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
              "| label size | samples | worst label PSNR (dB) |", "|---|---|---|"]
    for r in report["label"]:
        value = "inf (identical)" if math.isinf(r["min_psnr_db"]) else f"{r['min_psnr_db']:.1f}"
        lines.append(f"| {r['size']} | {r['samples']} | {value} |")
    lines += ["", "Target: >= 45 dB.", "", f"Measured in {report['seconds']:.0f} s."]
    return "\n".join(lines)
