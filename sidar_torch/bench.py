"""The speed benchmark: ``python -m sidar_torch bench [--quick]``.

In one process and one run, for every preset and output size it measures:

* **main process**: seconds per sequence (median over the measured samples; one warm-up sample
  before them, which compiles shaders, is reported on its own), sequences/s, views/s, and where
  the time goes: the median seconds of each step (:data:`STEPS`), from the ``timings``
  instrumentation of :func:`sidar_torch.dataset.render_sample` and the renderer;
* **DataLoader** with ``w`` workers (default fork start method): steady-state sequences/s over
  the same samples as the main process. Worker ``k`` first makes a warm-up sample (start-up,
  shader compilation), then samples ``k, k + w, ...``, and stamps each with its clock when made.
  The rate is ``w`` times the measured samples over the summed time each worker spent on its
  share (from its warm-up stamp to its last stamp: making, handing over and any wait for the
  main process), so workers that got cheaper samples than others do not inflate it. The
  main-process wall-clock rate over the same samples is kept in the JSON
  (``wall_sequences_per_s``);
* the **kornia 2-D baseline** at the same size: RandomPerspective + ColorJitter +
  RandomPlasmaShadow + RandomGaussianNoise on one ``(1, 3, H, W)`` float image, median seconds
  per image, and the ratio of our per-view cost (seconds per sequence / views) to it;
* **memory**: peak resident set size (``ru_maxrss``) of this process and of the largest worker,
  and the growth of this process's resident set over the measured samples, MB (2^20 bytes), with
  the part of it that is new pooled shadow maps (the renderer keeps one per spot light of the
  busiest view so far, 4 MB each at 1024^2: bounded, not a leak).

Times are wall-clock seconds from ``time.perf_counter`` (the tables show ms where marked). Torch
runs one thread in this process for the whole run, as it does in DataLoader workers, and
llvmpipe rasterises in the calling thread (``LP_NUM_THREADS=0``), so main-process figures are
per core. Linux only (``/proc``, ``ru_maxrss`` in kB).
"""

from __future__ import annotations

import itertools
import os
import platform
import resource
import statistics
import time
from collections import defaultdict
from dataclasses import asdict, dataclass, field
from typing import Any, Callable, Iterator

import torch
from torch.utils.data import DataLoader, IterableDataset, get_worker_info

from .config import SidarConfig, available_presets, load_config
from .dataset import SidarDataset, render_sample
from .render import RenderSettings, shared_renderer
from .scene import sample_sequence
from .timing import timed

__all__ = ["BenchSettings", "STEPS", "format_report", "run_bench", "timed_sample"]

STEPS = ("scene", "painting", "upload", "graph", "shadow", "colour", "mask", "opacity", "label", "readback",
         "effects", "homographies", "tensors")
"""Steps of a sample, in order: scene sampling, painting (source image fitted to the size),
texture and mesh uploads, pyrender scene graphs, shadow-map passes, lit colour passes, mask
passes, opacity passes (with ``opacity_output``), label pass, glReadPixels, view effects (when
on), homographies, tensor conversion."""

DEFAULT_PRESET = "misaligned"
"""The preset ``SidarDataset`` uses when given none; the targets refer to it."""

TARGETS = {"seconds_per_sequence": 0.2, "kornia_ratio": 1.0, "scaling_2_workers": 1.8, "rss_growth_mb": 10.0}
"""Goals of the speed issue (reported, never asserted): default preset at 512x384 with 6 views
in 0.2 s per sequence per core; per-view cost at most the kornia pipeline's per image; 2
workers at least 1.8x one; resident memory flat (here: under 10 MB of growth per run besides
new pooled shadow maps)."""

_WARMUP_INDEX = 1_000_000
"""Index of the warm-up sample, apart from the measured indices ``0 .. samples - 1``."""


def check_sizes(sizes: tuple[tuple[int, int], ...]) -> None:
    """Raise ``ValueError`` naming ``sizes`` unless every entry is an ``(H, W)`` pair of positive integers."""
    if any(len(s) != 2 or min(s) < 1 for s in sizes):
        raise ValueError(f"sizes: expected (H, W) pairs of positive integers, got {sizes}")


@dataclass(frozen=True)
class BenchSettings:
    """What the benchmark measures.

    Attributes:
        presets: preset names (``configs/*.yaml``).
        sizes: output sizes ``(H, W)`` in pixels.
        workers: ``0`` for the main-process measurement (with the time breakdown), ``w >= 1`` for
            a DataLoader with ``w`` workers.
        samples: measured samples per row (DataLoader rows round up to a multiple of ``w``).
        kornia_images: measured calls of the kornia pipeline per size.
        overrides: config fields applied to every preset (``image_size`` comes from ``sizes``).
        seed: dataset seed.
    """

    presets: tuple[str, ...] = tuple(available_presets())
    sizes: tuple[tuple[int, int], ...] = ((192, 256), (384, 512), (768, 1024))
    workers: tuple[int, ...] = (0, 1, 2)
    samples: int = 8
    kornia_images: int = 10
    overrides: dict[str, Any] = field(default_factory=dict)
    seed: int = 0

    def __post_init__(self) -> None:
        if not self.presets or not self.sizes or not self.workers:
            raise ValueError("presets, sizes and workers: expected at least one each")
        check_sizes(self.sizes)
        if any(w < 0 for w in self.workers):
            raise ValueError(f"workers: expected counts >= 0, got {self.workers}")
        if self.samples < 1 or self.kornia_images < 1:
            raise ValueError(f"samples, kornia_images: expected >= 1, got {self.samples}, {self.kornia_images}")
        if "image_size" in self.overrides:
            raise ValueError("overrides: image_size comes from sizes; leave it out")

    @classmethod
    def quick(cls, **changes: Any) -> "BenchSettings":
        """Under a minute on 2 cores: 256x192, two presets, 4 samples, main process, 1 and 2 workers."""
        return cls(**{"presets": (DEFAULT_PRESET, "ambient"), "sizes": ((192, 256),), "workers": (0, 1, 2),
                      "samples": 4, "kornia_images": 5, **changes})


def _size_label(size: tuple[int, int]) -> str:
    return f"{size[1]}x{size[0]}"


def _rss_mb() -> float:
    """Current resident set size of this process, MB (``nan`` without ``/proc``)."""
    try:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20
    except (OSError, ValueError):
        return float("nan")


def _peak_mb(who: int) -> float:
    """Peak resident set size (``ru_maxrss``, kB on Linux) of this process or its largest
    terminated child, MB."""
    return resource.getrusage(who).ru_maxrss / 1024


def timed_sample(dataset: SidarDataset, index: int) -> dict[str, float]:
    """Make sample ``index`` as :meth:`SidarDataset.sample` does, one timed step at a time.

    Returns:
        seconds per step (keys of :data:`STEPS` that ran) and ``"total"``, the whole sample.
    """
    timings: dict[str, float] = {}
    start = time.perf_counter()
    with timed(timings, "scene"):
        rng = dataset.generator(index)
        sequence = sample_sequence(dataset.config, rng)
    with timed(timings, "painting"):
        painting = dataset.source.painting(index % len(dataset.source), dataset.config.image_size)
    render_sample(sequence, painting, dataset.config, index, timings, rng)
    timings["total"] = time.perf_counter() - start
    return timings


def measure_main(config: SidarConfig, samples: int, seed: int) -> dict[str, Any]:
    """Samples in this process: median seconds per sequence and per step, warm-up, memory."""
    dataset = SidarDataset(config=config, seed=seed)
    warmup = timed_sample(dataset, _WARMUP_INDEX)["total"]
    renderer = shared_renderer(RenderSettings.from_config(config))
    rss_before, maps_before = _rss_mb(), renderer.shadow_map_count
    runs = [timed_sample(dataset, index) for index in range(samples)]
    new_maps_mb = (renderer.shadow_map_count - maps_before) * config.shadow_map_size**2 * 4 / 2**20
    steps = {key: statistics.median(r.get(key, 0.0) for r in runs) for key in STEPS}
    steps["other"] = statistics.median(r["total"] - sum(r.get(key, 0.0) for key in STEPS) for r in runs)
    total = statistics.median(r["total"] for r in runs)
    return {"samples": samples, "seconds_per_sequence": total, "sequences_per_s": 1 / total,
            "views_per_s": config.n_views / total, "ms_per_view": 1e3 * total / config.n_views,
            "warmup_s": warmup, "steps_s": steps, "rss_growth_mb": _rss_mb() - rss_before,
            "new_shadow_maps_mb": new_maps_mb, "peak_mb": _peak_mb(resource.RUSAGE_SELF)}


class _Stamped(IterableDataset):
    """Worker ``k`` of ``w``: a warm-up sample, then samples ``k, k + w, k + 2w, ...`` of
    ``dataset`` (endless), each with ``"worker"`` (``k``) and ``"done"`` (the worker's
    ``perf_counter`` when the sample was made, seconds) added."""

    def __init__(self, dataset: SidarDataset):
        super().__init__()
        self.dataset = dataset

    def __iter__(self) -> Iterator[dict[str, Any]]:
        info = get_worker_info()
        k, w = (info.id, info.num_workers) if info is not None else (0, 1)
        for index in itertools.chain([_WARMUP_INDEX + k], itertools.count(k, w)):
            yield {**self.dataset.sample(index), "worker": k, "done": time.perf_counter()}


def measure_loader(config: SidarConfig, workers: int, samples: int, seed: int) -> dict[str, Any]:
    """Steady-state sequences/s through a DataLoader with ``workers`` forked workers, over samples
    ``0 .. n - 1`` (``n``: ``samples`` rounded up to a multiple of ``workers``)."""
    per_worker = -(-samples // workers)
    loader = iter(DataLoader(_Stamped(SidarDataset(config=config, seed=seed)), batch_size=None,
                             num_workers=workers))
    stamps: dict[int, list[float]] = defaultdict(list)
    indices = []
    start = time.perf_counter()
    for n in range(workers * (1 + per_worker)):  # in-order delivery: round robin over the workers
        sample = next(loader)
        stamps[sample["worker"]].append(sample["done"])
        if n == workers - 1:  # every worker's warm-up sample is in
            warm = time.perf_counter()
        elif n >= workers:
            indices.append(sample["index"])
    wall = time.perf_counter() - warm
    del loader, sample  # shuts the workers down, so RUSAGE_CHILDREN includes them
    if indices != list(range(workers * per_worker)):
        raise RuntimeError(f"DataLoader delivered samples {indices}, not round robin over its workers")
    busy = sum(s[-1] - s[0] for s in stamps.values())
    rate = workers * workers * per_worker / busy
    return {"workers": workers, "samples": workers * per_worker, "sequences_per_s": rate,
            "views_per_s": rate * config.n_views, "wall_sequences_per_s": workers * per_worker / wall,
            "warmup_s": warm - start, "peak_mb": _peak_mb(resource.RUSAGE_CHILDREN)}


def kornia_seconds_per_image(size: tuple[int, int], images: int, seed: int) -> float:
    """Median seconds of kornia's 2-D pipeline on one ``(1, 3, H, W)`` float image (batch 1, every
    augmentation applied; one untimed call first)."""
    import kornia.augmentation as KA

    torch.manual_seed(seed)
    pipeline = torch.nn.Sequential(
        KA.RandomPerspective(0.5, p=1.0), KA.ColorJitter(0.2, 0.2, 0.2, 0.05, p=1.0),
        KA.RandomPlasmaShadow(p=1.0), KA.RandomGaussianNoise(std=0.05, p=1.0))
    image = torch.rand(1, 3, *size)
    times = []
    with torch.no_grad():
        for _ in range(images + 1):
            start = time.perf_counter()
            pipeline(image)
            times.append(time.perf_counter() - start)
    return statistics.median(times[1:])


def run_bench(settings: BenchSettings, log: Callable[[str], None] = print) -> dict[str, Any]:
    """Every measurement, as plain data (see :func:`format_report`); ``log`` gets progress lines."""
    start, load_start, threads = time.perf_counter(), os.getloadavg(), torch.get_num_threads()
    torch.set_num_threads(1)
    kornia, runs = [], []
    try:
        for size in settings.sizes:
            kornia_s = kornia_seconds_per_image(size, settings.kornia_images, settings.seed)
            kornia.append({"size": _size_label(size), "ms_per_image": 1e3 * kornia_s})
            log(f"kornia at {_size_label(size)}: {1e3 * kornia_s:.1f} ms per image")
            for preset in settings.presets:
                config = load_config(preset, **settings.overrides, image_size=size)
                run = {"preset": preset, "size": _size_label(size), "views": config.n_views, "main": None,
                       "loaders": []}
                for workers in settings.workers:
                    if workers == 0:
                        run["main"] = main = measure_main(config, settings.samples, settings.seed)
                        main["kornia_ratio"] = main["ms_per_view"] / (1e3 * kornia_s)
                    else:
                        run["loaders"].append(measure_loader(config, workers, settings.samples, settings.seed))
                    log(f"{preset} at {_size_label(size)}, {workers or 'main process'}"
                        f"{' worker(s)' if workers else ''}: done ({time.perf_counter() - start:.0f} s)")
                _add_scaling(run)
                runs.append(run)
    finally:
        torch.set_num_threads(threads)
    report = {"settings": asdict(settings), "machine": _machine(load_start), "kornia": kornia, "runs": runs,
              "seconds": time.perf_counter() - start}
    report["targets"] = _targets(report)
    return report


def _add_scaling(run: dict[str, Any]) -> None:
    """Each loader's rate over the 1-worker rate (or, without that row, the main process's)."""
    one = [r["sequences_per_s"] for r in run["loaders"] if r["workers"] == 1]
    base = one[0] if one else (run["main"] or {}).get("sequences_per_s")
    for r in run["loaders"]:
        r["scaling"] = r["sequences_per_s"] / base if base else None
        r["scaling_base"] = "1 worker" if one else "main process" if base else None


def _machine(load_start: tuple[float, float, float]) -> dict[str, Any]:
    import kornia

    from .render.context import GL_PLATFORM

    return {"cpus": os.cpu_count(), "load_start": load_start[0], "load_end": os.getloadavg()[0],
            "python": platform.python_version(), "torch": torch.__version__, "kornia": kornia.__version__,
            "gl_platform": GL_PLATFORM, "lp_num_threads": os.environ.get("LP_NUM_THREADS")}


def _targets(report: dict[str, Any]) -> list[dict[str, Any]]:
    """The issue's targets against the default preset at 512x384 (or the first size measured)."""
    runs = [r for r in report["runs"] if r["preset"] == DEFAULT_PRESET]
    run = next((r for r in runs if r["size"] == "512x384"), runs[0] if runs else None)
    if run is None:
        return []
    where = f"{DEFAULT_PRESET} at {run['size']}, {run['views']} views"
    if run["size"] != "512x384":
        where += "; the target is for 512x384"
    main, rows = run["main"], []
    if main:
        top = sorted(main["steps_s"].items(), key=lambda kv: -kv[1])[:3]
        parts = ", ".join(f"{k} {100 * v / main['seconds_per_sequence']:.0f} %" for k, v in top)
        rows.append({"target": f"<= {TARGETS['seconds_per_sequence']} s per sequence per core ({where})",
                     "measured": f"{main['seconds_per_sequence']:.3f} s (largest steps: {parts})",
                     "met": main["seconds_per_sequence"] <= TARGETS["seconds_per_sequence"]})
        rows.append({"target": f"per-view cost <= kornia 2-D pipeline per image (ratio <= {TARGETS['kornia_ratio']})",
                     "measured": f"{main['ms_per_view']:.1f} ms / view, ratio {main['kornia_ratio']:.2f}",
                     "met": main["kornia_ratio"] <= TARGETS["kornia_ratio"]})
    two = [r for r in run["loaders"] if r["workers"] == 2 and r["scaling"] is not None]
    if two:
        rows.append({"target": f"2 workers >= {TARGETS['scaling_2_workers']}x one worker",
                     "measured": f"{two[0]['scaling']:.2f}x (against {two[0]['scaling_base']})",
                     "met": two[0]["scaling"] >= TARGETS["scaling_2_workers"]})
    mains = [r["main"] for r in report["runs"] if r["main"]]
    if mains:
        worst = max(mains, key=lambda x: x["rss_growth_mb"] - x["new_shadow_maps_mb"])
        rest = worst["rss_growth_mb"] - worst["new_shadow_maps_mb"]
        rows.append({"target": f"memory flat (RSS growth over a run's samples, besides new pooled shadow maps, "
                               f"< {TARGETS['rss_growth_mb']:.0f} MB)",
                     "measured": f"largest {rest:.1f} MB ({worst['rss_growth_mb']:.1f} MB growth, "
                                 f"{worst['new_shadow_maps_mb']:.0f} MB new shadow maps); peak "
                                 f"{max(_peaks(report)):.0f} MB",
                     "met": rest < TARGETS["rss_growth_mb"]})
    return rows


def _peaks(report: dict[str, Any]) -> list[float]:
    return [x["peak_mb"] for r in report["runs"] for x in ([r["main"]] if r["main"] else []) + r["loaders"]]


def _fmt(value: float | None, spec: str) -> str:
    return "-" if value is None else format(value, spec)


def format_report(report: dict[str, Any]) -> str:
    """The report as markdown: throughput, time per step, kornia baseline, targets."""
    m, s = report["machine"], report["settings"]
    loaded = max(m["load_start"], m["load_end"]) > (m["cpus"] or 1)
    lines = ["# sidar_torch bench", "",
             f"{m['cpus']} cores, load average {m['load_start']:.2f} at start, {m['load_end']:.2f} at end"
             f"{' (loaded machine: other jobs ran, figures are pessimistic)' if loaded else ''}; "
             f"torch {m['torch']} on 1 thread, kornia {m['kornia']}, GL {m['gl_platform']}, "
             f"LP_NUM_THREADS={m['lp_num_threads']}; {s['samples']} samples per row; {report['seconds']:.0f} s.",
             "", "## Throughput", "",
             "| preset | size | process | s / sequence | sequences/s | views/s | ms / view | vs kornia | scaling "
             "| peak MB |", "|---|---|---|---|---|---|---|---|---|---|"]
    for r in report["runs"]:
        if r["main"]:
            x = r["main"]
            lines.append(f"| {r['preset']} | {r['size']} | main | {x['seconds_per_sequence']:.3f} "
                         f"| {x['sequences_per_s']:.2f} | {x['views_per_s']:.1f} | {x['ms_per_view']:.1f} "
                         f"| {x['kornia_ratio']:.2f} | | {x['peak_mb']:.0f} |")
        for x in r["loaders"]:
            lines.append(f"| {r['preset']} | {r['size']} | {x['workers']} worker{'s' * (x['workers'] > 1)} | "
                         f"| {x['sequences_per_s']:.2f} | {x['views_per_s']:.1f} | | | {_fmt(x['scaling'], '.2f')}x "
                         f"| {x['peak_mb']:.0f} |")
    lines += ["", "main: median over the samples after a warm-up sample, this process. Workers: steady state "
              "after each worker's first sample. vs kornia: ms per view over kornia's ms per image at that "
              "size. scaling: over the 1-worker rate (over the main process's without a 1-worker row). "
              "peak MB: ru_maxrss of this process (main) or of the largest worker so far.",
              "", "## Where the time goes (main process, median ms per sequence)", "",
              "| preset | size | total | " + " | ".join(STEPS) + " | other | warm-up s | RSS growth MB "
              "(new shadow maps) |", "|---|---|---|" + "---|" * (len(STEPS) + 3)]
    for r in report["runs"]:
        if r["main"]:
            x = r["main"]
            steps = " | ".join(f"{1e3 * x['steps_s'][k]:.1f}" for k in (*STEPS, "other"))
            lines.append(f"| {r['preset']} | {r['size']} | {1e3 * x['seconds_per_sequence']:.1f} | {steps} "
                         f"| {x['warmup_s']:.2f} | {x['rss_growth_mb']:.1f} ({x['new_shadow_maps_mb']:.0f}) |")
    lines += ["", "## Kornia 2-D baseline (RandomPerspective + ColorJitter + RandomPlasmaShadow + "
              "RandomGaussianNoise, batch 1, one thread)", "", "| size | ms / image |", "|---|---|"]
    lines += [f"| {k['size']} | {k['ms_per_image']:.1f} |" for k in report["kornia"]]
    if report["targets"]:
        lines += ["", "## Targets (reported, not asserted)", "", "| target | measured | met |", "|---|---|---|"]
        lines += [f"| {t['target']} | {t['measured']} | {'yes' if t['met'] else 'no'} |" for t in report["targets"]]
    return "\n".join(lines)
