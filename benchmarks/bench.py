"""The speed benchmark: ``python -m benchmarks.bench [--quick]`` from the repository root (docs/speed.md).

In one process and one run (torch on one thread, llvmpipe in the calling thread), it measures:

* **views**: for each size (default 24x32, 192x256, 384x512, 768x1024, ``HxW``) and preset (default
  ``misaligned``: 6 views with masks, label and every homography), the median process CPU time of
  ``SidarDataset.sample(i)`` over ``--samples`` samples after one warm-up sample (shader
  compilation, reported on its own), per sequence and per view; and kornia's 2-D pipeline
  (:func:`benchmarks.common.kornia_pipeline`, batch 1) per image at the same size, median CPU
  time of calls made between the samples (so both meet the same state of a shared machine); the
  ratio of the two;
* **augment**: ``SidarAugment(preset, n_views=2, image_size=192x256)`` on a batch of 8 images,
  median CPU time per call after a warm-up call, per image, against kornia's pipeline on the same
  batch per image and against its first two steps alone (RandomPerspective + ColorJitter,
  :func:`benchmarks.common.plain_pipeline`), the calls of both between ours; with a render pool
  (``num_workers=2``, when ``SidarAugment`` has one), the wall-clock throughput of the pool over the
  single-process one;
* **workers**: steady-state sequences/s of the preset at 384x512 through a DataLoader with 1 and
  2 workers (wall clock; see :func:`loader_rate`) and their ratio, and where the first sample of the
  fresh worker went (its start, its warm-up, the sample, the handover);
* **targets**: each speed goal of :data:`TARGETS`, met or not, with its figure.

The figures are printed as markdown (and written as JSON with ``--json PATH``); nothing is asserted.
``--parts augment`` measures the augment row alone (about 15 s), with the machine's load before and after.
"""

from __future__ import annotations

import argparse
import inspect
import itertools
import json
import sys
import time
from collections import defaultdict
from dataclasses import asdict, dataclass
from typing import Any, Callable, Iterator, Sequence

import torch
from torch.utils.data import DataLoader, IterableDataset, get_worker_info

from sidar_torch import SidarAugment, SidarDataset, load_config

from .common import (DEFAULT_PRESET, cpu_seconds, kornia_call, machine, machine_line, median, one_thread,
                     parse_size, plain_pipeline, size_label, warm_heap)

__all__ = ["BenchSettings", "build_parser", "format_report", "loader_rate", "main", "run_bench", "targets"]

_WARMUP_INDEX = 1_000_000
"""Index of warm-up samples, apart from the measured indices ``0 .. samples - 1``."""

HEAPS = ("warm", "cold")
"""The heap states a run can measure in (``BenchSettings.heap``)."""

PARTS = ("views", "augment", "workers")
"""What a run can measure (``BenchSettings.parts``): the per-view rows, the ``SidarAugment`` row, the
DataLoader rows."""

TARGET_SIZES = {"tiny": (24, 32), "small": (192, 256), "default": (384, 512)}
"""The sizes the speed goals name, ``(H, W)``."""

TARGETS = {"seconds_per_sequence": 0.2, "kornia_ratio": {"tiny": 1.6, "small": 1.3, "default": 1.1},
           "augment_ratio": 2.5, "pool_speedup": 1.8, "worker_scaling": 1.8, "first_sample_s": 0.5}
"""The speed goals: the default preset at 384x512 (6 views) in 0.2 s of CPU per sequence; per-view
cost at most 1.6x kornia's per image at 24x32 (a view's fixed cost), 1.3x at 192x256 and 1.1x at 384x512;
``SidarAugment`` (batch 8, 2 views, 192x256) at most 2.5x kornia per image on one core, and a pool of
2 render processes at least 1.8x its single-process throughput; 2 DataLoader workers at least 1.8x
one; a fresh DataLoader worker's first sample within 0.5 s of asking for it (wall clock)."""


@dataclass(frozen=True)
class BenchSettings:
    """What the benchmark measures.

    Attributes:
        presets: preset names or YAML paths for the per-view rows (targets: :data:`DEFAULT_PRESET`).
        sizes: output sizes ``(H, W)`` of the per-view rows.
        samples: measured samples per per-view row, after one warm-up sample (samples
            ``0 .. samples - 1``). One scene may cost three times another, so a median needs many:
            samples 0-11 happen to be cheap ones (docs/speed.md).
        kornia_calls: kornia calls timed after each measured sample (and each ``SidarAugment`` call).
        augment_batch, augment_views, augment_size: the ``SidarAugment`` batch, views and ``(H, W)``.
        augment_calls: measured ``SidarAugment`` calls, after one warm-up call.
        loader_size: ``(H, W)`` of the DataLoader rows.
        loader_samples: measured samples of each DataLoader row: samples ``0 .. loader_samples - 1``
            with 1 worker and with 2 (even, at least 2), so that the rows' ratio compares the same work.
        views: views per sequence (``None``: each preset's own).
        seed: dataset and module seed.
        heap: ``"warm"`` (:func:`~benchmarks.common.warm_heap` before measuring: no side pays page
            faults for fresh memory, as in a long training run) or ``"cold"`` (glibc's defaults, as
            a fresh process has them: what faults depends on what ran before).
        parts: what to measure, names of :data:`PARTS` (default all); the report holds ``[]``
            (views) or ``None`` (augment, loaders) for a part not measured.
    """

    presets: tuple[str, ...] = (DEFAULT_PRESET,)
    sizes: tuple[tuple[int, int], ...] = (*TARGET_SIZES.values(), (768, 1024))
    samples: int = 48
    kornia_calls: int = 3
    augment_batch: int = 8
    augment_views: int = 2
    augment_size: tuple[int, int] = TARGET_SIZES["small"]
    augment_calls: int = 5
    loader_size: tuple[int, int] = TARGET_SIZES["default"]
    loader_samples: int = 24
    views: int | None = None
    seed: int = 0
    heap: str = "warm"
    parts: tuple[str, ...] = PARTS

    def __post_init__(self) -> None:
        if not self.presets or not self.sizes:
            raise ValueError("presets, sizes: expected at least one each")
        for size in (*self.sizes, self.augment_size, self.loader_size):
            if len(size) != 2 or min(size) < 1:
                raise ValueError(f"sizes: expected (H, W) pairs of positive integers, got {size}")
        counts = {"samples": self.samples, "kornia_calls": self.kornia_calls, "augment_batch": self.augment_batch,
                  "augment_views": self.augment_views, "augment_calls": self.augment_calls,
                  "loader_samples": self.loader_samples}
        bad = {k: v for k, v in counts.items() if v < 1}
        if bad or (self.views is not None and self.views < 1):
            raise ValueError(f"{', '.join(bad) or 'views'}: expected >= 1, got {bad or self.views}")
        if self.loader_samples % 2:
            raise ValueError(f"loader_samples: expected an even number (the same samples for 1 and 2 workers), "
                             f"got {self.loader_samples}")
        if self.heap not in HEAPS:
            raise ValueError(f"heap: expected one of {HEAPS}, got {self.heap!r}")
        if not self.parts or set(self.parts) - set(PARTS):
            raise ValueError(f"parts: expected one or more of {PARTS}, got {self.parts}")
        for preset in self.presets:  # unknown presets fail before measuring anything
            load_config(preset)

    @classmethod
    def quick(cls, **changes: Any) -> "BenchSettings":
        """Seconds, for tests: one 48x64 size, 2 views, 2 samples, a batch of 2, 2 loader samples."""
        tiny = (48, 64)
        return cls(**{"sizes": (tiny,), "samples": 2, "kornia_calls": 1, "augment_batch": 2, "augment_size": tiny,
                      "augment_calls": 1, "loader_size": tiny, "loader_samples": 4, "views": 2, "heap": "cold",
                      **changes})


def _config(preset: str, size: tuple[int, int], views: int | None) -> Any:
    return load_config(preset, image_size=size, **({} if views is None else {"n_views": views}))


def alternated(measured: Callable[[int], object], baseline: Callable[[], object], calls: int,
               baseline_calls: int) -> tuple[float, float]:
    """Median CPU seconds of ``measured(k)`` for ``k`` in ``0 .. calls - 1`` and of ``baseline()``,
    timed ``baseline_calls`` times after each of them: a machine that slows down or speeds up
    during the run moves both."""
    ours, (theirs,) = alternated_baselines(measured, [baseline], calls, baseline_calls)
    return ours, theirs


def alternated_baselines(measured: Callable[[int], object], baselines: Sequence[Callable[[], object]], calls: int,
                         baseline_calls: int) -> tuple[float, list[float]]:
    """:func:`alternated` with several baselines: after each ``measured(k)``, each of ``baselines``
    timed ``baseline_calls`` times in turn; the median of ours and of each baseline's."""
    ours, theirs = [], [[] for _ in baselines]
    for k in range(calls):
        ours.append(cpu_seconds(lambda: measured(k)))
        for baseline, seconds in zip(baselines, theirs):
            seconds += [cpu_seconds(baseline) for _ in range(baseline_calls)]
    return median(ours), [median(seconds) for seconds in theirs]


def view_row(preset: str, size: tuple[int, int], settings: BenchSettings) -> dict[str, Any]:
    """Median CPU seconds per sequence and per view of ``preset`` at ``size``, against kornia."""
    config = _config(preset, size, settings.views)
    dataset = SidarDataset(config=config, seed=settings.seed)
    # Every shader variant, then one sample (a fresh process hands its first sample out before its warm-up).
    warmup = cpu_seconds(lambda: (dataset.warm_up(), dataset.sample(_WARMUP_INDEX)))
    per_sequence, kornia_s = alternated(dataset.sample, kornia_call(1, size, settings.seed), settings.samples,
                                        settings.kornia_calls)
    per_view = per_sequence / config.n_views
    return {"preset": preset, "size": size_label(size), "views": config.n_views, "samples": settings.samples,
            "s_per_sequence": per_sequence, "ms_per_view": 1e3 * per_view, "warmup_s": warmup,
            "kornia_ms_per_image": 1e3 * kornia_s, "kornia_ratio": per_view / kornia_s}


def augment_row(settings: BenchSettings) -> dict[str, Any]:
    """``SidarAugment`` per image (median CPU time per call over the batch) against kornia's pipeline
    and against its plain RandomPerspective + ColorJitter on the same batch; with a render pool, its
    wall-clock throughput over the single-process one."""
    preset, batch, size = settings.presets[0], settings.augment_batch, settings.augment_size
    images = torch.rand(batch, 3, *size, generator=torch.Generator().manual_seed(settings.seed))
    serial = SidarAugment(preset, seed=settings.seed, n_views=settings.augment_views, image_size=size)
    serial(images)  # warm-up: shaders
    baselines = [kornia_call(batch, size, settings.seed), kornia_call(batch, size, settings.seed, plain_pipeline)]
    per_call, (kornia_per_call, plain_per_call) = alternated_baselines(
        lambda _: serial(images), baselines, settings.augment_calls, settings.kornia_calls)
    per_image, kornia_s, plain_s = per_call / batch, kornia_per_call / batch, plain_per_call / batch
    row = {"preset": preset, "batch": batch, "views": settings.augment_views, "size": size_label(size),
           "ms_per_image": 1e3 * per_image, "kornia_ms_per_image": 1e3 * kornia_s, "kornia_ratio": per_image / kornia_s,
           "plain_ms_per_image": 1e3 * plain_s, "plain_ratio": per_image / plain_s, "pool_speedup": None}
    if "num_workers" in inspect.signature(SidarAugment).parameters:
        pooled = SidarAugment(preset, seed=settings.seed, n_views=settings.augment_views, image_size=size,
                              num_workers=2)
        pooled(images)  # warm-up: starts the pool, shaders in every process
        wall = {name: median(_wall_seconds(lambda: module(images)) for _ in range(settings.augment_calls))
                for name, module in (("serial", serial), ("pool", pooled))}
        row["pool_speedup"] = wall["serial"] / wall["pool"]
        del pooled
    return row


def _wall_seconds(call: Callable[[], object]) -> float:
    start = time.perf_counter()
    call()
    return time.perf_counter() - start


class _Stamped(IterableDataset):
    """Worker ``k`` of ``w``: the dataset's worker warm-up (:meth:`SidarDataset.warm_up`, as its own
    ``__iter__`` does), a warm-up sample, then samples ``k, k + w, k + 2w, ...`` of ``dataset``
    (endless), each with ``"worker"`` (``k``), ``"done"`` (the worker's ``perf_counter`` when the
    sample was made, seconds), ``"started"`` (when the worker began iterating) and ``"warmed"``
    (when its warm-up ended) added. ``perf_counter`` is the system's monotonic clock on Linux, so
    the stamps of all processes compare."""

    def __init__(self, dataset: SidarDataset):
        super().__init__()
        self.dataset = dataset

    def __iter__(self) -> Iterator[dict[str, Any]]:
        info = get_worker_info()
        k, w = (info.id, info.num_workers) if info is not None else (0, 1)
        started = time.perf_counter()
        self.dataset.warm_up()
        warmed = time.perf_counter()
        for index in itertools.chain([_WARMUP_INDEX + k], itertools.count(k, w)):
            yield {**self.dataset.sample(index), "worker": k, "done": time.perf_counter(), "started": started,
                   "warmed": warmed}


def loader_rate(config: Any, workers: int, samples: int, seed: int) -> tuple[float, dict[str, float]]:
    """Steady-state sequences/s through a DataLoader with ``workers`` (default start method) workers,
    and where the first sample's wall time went, from creating the loader's iterator (which starts
    the workers): ``{"total", "start", "warm_up", "sample", "handover"}`` seconds (the first worker
    starts iterating, its warm-up, its warm-up sample, the sample's way back to this process).

    Each worker warms up and makes a warm-up sample, then its share of the measured samples
    ``0 .. samples - 1`` (round robin: ``samples / workers`` each), stamping each with its clock.
    The rate is ``workers`` times the measured samples over the summed time each worker spent on
    its share (warm-up sample's stamp to last stamp: making, handing over, any wait for this
    process), so a worker that drew cheaper samples does not inflate it. Rates of runs with other
    ``workers`` but the same ``samples`` compare the same work (one scene may cost twice another, so
    two sets of samples differ in their mean cost).
    """
    if samples < workers or samples % workers:
        raise ValueError(f"samples: expected a positive multiple of workers ({workers}), got {samples}")
    per_worker = samples // workers
    begin = time.perf_counter()
    loader = iter(DataLoader(_Stamped(SidarDataset(config=config, seed=seed)), batch_size=None,
                             num_workers=workers))
    stamps: dict[int, list[float]] = defaultdict(list)
    indices = []
    for n in range(workers * (1 + per_worker)):  # in-order delivery: round robin over the workers
        sample = next(loader)
        if n == 0:
            end = time.perf_counter()
            first = {"total": end - begin, "start": sample["started"] - begin,
                     "warm_up": sample["warmed"] - sample["started"], "sample": sample["done"] - sample["warmed"],
                     "handover": end - sample["done"]}
        stamps[sample["worker"]].append(sample["done"])
        if n >= workers:
            indices.append(sample["index"])
    del loader  # shuts the workers down
    if indices != list(range(workers * per_worker)):
        raise RuntimeError(f"DataLoader delivered samples {indices}, not round robin over its workers")
    busy = sum(s[-1] - s[0] for s in stamps.values())
    return workers * workers * per_worker / busy, first


def run_bench(settings: BenchSettings, log: Callable[[str], None] = print) -> dict[str, Any]:
    """Every measurement, as plain data (see :func:`format_report`); ``log`` gets progress lines.
    With ``settings.heap`` ``"warm"`` it first calls :func:`~benchmarks.common.warm_heap` (for the
    rest of the process)."""
    heap = settings.heap if settings.heap == "cold" or warm_heap() else "cold (no glibc mallopt)"
    start, before = time.perf_counter(), machine()
    rows, augment, loaders = [], None, None
    with one_thread():
        if "views" in settings.parts:
            for size in settings.sizes:
                for preset in settings.presets:
                    rows.append(view_row(preset, size, settings))
                    log(f"{preset} at {size_label(size)}: done ({time.perf_counter() - start:.0f} s)")
        if "augment" in settings.parts:
            augment = augment_row(settings)
            log(f"SidarAugment: done ({time.perf_counter() - start:.0f} s)")
        if "workers" in settings.parts:
            loaders = loader_row(settings)
            log(f"DataLoader 1 and 2 workers: done ({time.perf_counter() - start:.0f} s)")
    report = {"settings": asdict(settings), "heap": heap, "machine": {"before": before, "after": machine()}, "views": rows,
              "augment": augment, "loaders": loaders, "seconds": time.perf_counter() - start}
    report["targets"] = targets(report)
    return report


def loader_row(settings: BenchSettings) -> dict[str, Any]:
    """The DataLoader rows: sequences/s with 1 and 2 workers (:func:`loader_rate`), their ratio and
    where the first sample of the fresh worker went."""
    config = _config(settings.presets[0], settings.loader_size, settings.views)
    measured = {w: loader_rate(config, w, settings.loader_samples, settings.seed) for w in (1, 2)}
    rates = {w: rate for w, (rate, _) in measured.items()}
    return {"preset": settings.presets[0], "size": size_label(settings.loader_size), "views": config.n_views,
            "samples": settings.loader_samples, "sequences_per_s": {str(w): r for w, r in rates.items()},
            "scaling": rates[2] / rates[1], "first_sample_s": measured[1][1]["total"], "first_sample": measured[1][1]}


def targets(report: dict[str, Any]) -> list[dict[str, Any]]:
    """The speed goals (:data:`TARGETS`) against the report: ``{"target", "measured", "met"}`` each; ``met`` is
    ``None`` (and ``measured`` says why) where the run did not measure what the target names."""
    rows = []

    def add(target: str, measured: str | None, met: bool | None) -> None:
        rows.append({"target": target, "measured": measured or "not measured in this run", "met": met})

    views = {(r["preset"], r["size"]): r for r in report["views"]}
    default = views.get((DEFAULT_PRESET, size_label(TARGET_SIZES["default"])))
    ok = default is not None and default["views"] == 6
    limit = TARGETS["seconds_per_sequence"]
    add(f"{DEFAULT_PRESET} {size_label(TARGET_SIZES['default'])}, 6 views: <= {limit} s CPU per sequence",
        f"{default['s_per_sequence']:.3f} s" if ok else None, default["s_per_sequence"] <= limit if ok else None)
    for name, size in TARGET_SIZES.items():
        row, limit = views.get((DEFAULT_PRESET, size_label(size))), TARGETS["kornia_ratio"][name]
        add(f"{DEFAULT_PRESET} {size_label(size)}: per view <= {limit}x kornia per image",
            row and f"{row['kornia_ratio']:.2f}x ({row['ms_per_view']:.1f} ms against {row['kornia_ms_per_image']:.1f} ms)",
            row["kornia_ratio"] <= limit if row else None)
    a = report["augment"]
    ok = a is not None and (a["preset"], a["batch"], a["views"], a["size"]) == (
        DEFAULT_PRESET, 8, 2, size_label(TARGET_SIZES["small"]))
    limit = TARGETS["augment_ratio"]
    add(f"SidarAugment {DEFAULT_PRESET}, batch 8, 2 views, {size_label(TARGET_SIZES['small'])}: per image <= "
        f"{limit}x kornia on the same batch (one core)",
        ok and f"{a['kornia_ratio']:.2f}x ({a['ms_per_image']:.1f} ms against {a['kornia_ms_per_image']:.1f} ms)",
        a["kornia_ratio"] <= limit if ok else None)
    limit = TARGETS["pool_speedup"]
    pool = a and a["pool_speedup"]
    add(f"SidarAugment with a pool of 2 render processes: >= {limit}x its single-process throughput",
        a and ("no pool: SidarAugment has no num_workers" if pool is None else f"{pool:.2f}x (wall clock)"),
        None if a is None else False if pool is None else pool >= limit)
    loaders, limit = report["loaders"], TARGETS["worker_scaling"]
    load = max(m["load"] for m in report["machine"].values())
    add(f"2 DataLoader workers >= {limit}x one worker (on an idle machine)",
        loaders and f"{loaders['scaling']:.2f}x ({loaders['preset']} {loaders['size']}, load average up to {load:.1f} "
        f"on {report['machine']['before']['cpus']} cores)", loaders and loaders["scaling"] >= limit)
    limit = TARGETS["first_sample_s"]
    add(f"first sample of a fresh DataLoader worker, after this process rendered: <= {limit} s (wall clock)",
        loaders and f"{loaders['first_sample_s']:.2f} s", loaders and loaders["first_sample_s"] <= limit)
    return rows


def format_report(report: dict[str, Any]) -> str:
    """The report as markdown: per-view table, SidarAugment, DataLoader workers (those measured), targets."""
    m = report["machine"]
    lines = ["# sidar_torch speed (python -m benchmarks.bench)", "", machine_line(m["before"], m["after"]) +
             f"; heap {report['heap']}; {report['seconds']:.0f} s."]
    if report["views"]:
        lines += _views_table(report)
    if report["augment"] is not None:
        lines += _augment_table(report["augment"])
    if report["loaders"] is not None:
        lines += _loaders_table(report["loaders"])
    lines += ["", "## Targets (reported, never asserted)", "", "| target | measured | met |", "|---|---|---|"]
    verdict = {True: "met", False: "not met", None: "-"}
    lines += [f"| {t['target']} | {t['measured']} | {verdict[t['met']]} |" for t in report["targets"]]
    return "\n".join(lines)


def _views_table(report: dict[str, Any]) -> list[str]:
    s = report["settings"]
    lines = ["", "## Per view against kornia's 2-D pipeline (batch 1), process CPU time, one core", "",
             "| preset | size (H x W) | views | s / sequence | ms / view | kornia ms / image | ratio | warm-up s |",
             "|---|---|---|---|---|---|---|---|"]
    for r in report["views"]:
        lines.append(f"| {r['preset']} | {r['size']} | {r['views']} | {r['s_per_sequence']:.3f} | {r['ms_per_view']:.1f} "
                     f"| {r['kornia_ms_per_image']:.1f} | {r['kornia_ratio']:.2f}x | {r['warmup_s']:.2f} |")
    return lines + ["", f"Medians over {s['samples']} samples after a warm-up sample (the warm-up compiles shaders), "
                    f"and over kornia's calls, {s['kornia_calls']} after each sample. "
                    "Ratio: ms per view over kornia's ms per image at that size. Kornia's pipeline: RandomPerspective "
                    "+ ColorJitter + RandomPlasmaShadow + RandomGaussianNoise."]


def _augment_table(a: dict[str, Any]) -> list[str]:
    pool = "-" if a["pool_speedup"] is None else f"{a['pool_speedup']:.2f}x"
    return ["", "## SidarAugment against kornia on the same batch, process CPU time, one core", "",
            "| preset | batch | views | size (H x W) | ms / image | kornia ms / image | ratio "
            "| perspective + jitter ms / image | ratio | pool of 2 (wall) |",
            "|---|---|---|---|---|---|---|---|---|---|",
            f"| {a['preset']} | {a['batch']} | {a['views']} | {a['size']} | {a['ms_per_image']:.1f} "
            f"| {a['kornia_ms_per_image']:.1f} | {a['kornia_ratio']:.2f}x | {a['plain_ms_per_image']:.1f} "
            f"| {a['plain_ratio']:.2f}x | {pool} |", "",
            "Kornia: its four-step pipeline (RandomPerspective + ColorJitter + RandomPlasmaShadow + "
            "RandomGaussianNoise); perspective + jitter: its first two steps alone. Both timed on the same batch, "
            "between our calls."]


def _loaders_table(w: dict[str, Any]) -> list[str]:
    rates = w["sequences_per_s"]
    return ["", "## DataLoader workers (wall clock, steady state after each worker's first sample)", "",
            "| preset | size (H x W) | views | 1 worker seq/s | 2 workers seq/s | scaling | first sample s |",
            "|---|---|---|---|---|---|---|",
            f"| {w['preset']} | {w['size']} | {w['views']} | {rates['1']:.2f} | {rates['2']:.2f} "
            f"| {w['scaling']:.2f}x | {w['first_sample_s']:.2f} |",
            "", "First sample of the fresh worker (wall clock, s): " + ", ".join(
                f"{name} {w['first_sample'][key]:.3f}" for key, name in (
                    ("start", "worker start"), ("warm_up", "warm-up"), ("sample", "sample"),
                    ("handover", "handover"), ("total", "total"))) + "."]


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``python -m benchmarks.bench``; parsing it runs nothing."""
    parser = argparse.ArgumentParser(prog="python -m benchmarks.bench", description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true",
                        help="seconds: one 48x64 size, 2 views, tiny batches (for tests; no target is measured)")
    parser.add_argument("--presets", nargs="+", default=None, metavar="PRESET",
                        help=f"presets or YAML paths of the per-view rows; the first also runs SidarAugment and "
                             f"the DataLoader rows (default {DEFAULT_PRESET})")
    parser.add_argument("--sizes", nargs="+", type=parse_size, default=None, metavar="HxW",
                        help="per-view sizes, height x width (default 24x32 192x256 384x512 768x1024)")
    parser.add_argument("--samples", type=int, default=None, help="measured samples per per-view row (default 48)")
    parser.add_argument("--heap", choices=HEAPS, default=None,
                        help="warm: no page faults for fresh memory on either side, as in a long run (default); "
                             "cold: glibc's defaults, as in a fresh process")
    parser.add_argument("--parts", nargs="+", choices=PARTS, default=None, metavar="PART",
                        help=f"what to measure, among {', '.join(PARTS)} (default all; augment alone takes "
                             f"about 15 s)")
    parser.add_argument("--json", default=None, metavar="PATH", help="also write the figures as JSON to PATH")
    return parser


def main(argv: list[str] | None = None) -> None:
    args = build_parser().parse_args(argv)
    changes = {k: tuple(v) if isinstance(v, list) else v
               for k, v in {"presets": args.presets, "sizes": args.sizes, "samples": args.samples,
                            "heap": args.heap, "parts": args.parts}.items()
               if v is not None}
    try:
        settings = (BenchSettings.quick if args.quick else BenchSettings)(**changes)
    except (ValueError, FileNotFoundError) as error:
        raise SystemExit(f"bench: {error}") from error
    report = run_bench(settings, log=lambda line: print(line, file=sys.stderr))
    print(format_report(report))
    if args.json:
        with open(args.json, "w") as out:
            json.dump(report, out, indent=2)


if __name__ == "__main__":
    main()
