"""Time per view of the same scenes rendered two ways (two ``RenderSettings``), in one process: the
command line and clocks ``setting_cost`` and ``lens_cost`` share, and ``setting_cost``'s measurement.

Both renderers are this process's shared ones (one per setting); each sequence is rendered both
ways, alternating which goes first, after warm-up sequences (shader variants compile at first use).
Clocks: wall time and this process's CPU time (llvmpipe draws in this thread with
``LP_NUM_THREADS=0``, so CPU time is what other jobs on the machine disturb least).
"""

from __future__ import annotations

import argparse
import statistics
import time
from typing import Any

import numpy as np

from sidar_torch import SidarConfig, SidarDataset, load_config
from sidar_torch.timing import collect_timings

from .common import DEFAULT_PRESET, parse_set, parse_size

__all__ = ["CLOCKS", "paired_config", "paired_parser", "paired_settings_times", "print_paired"]

CLOCKS = {"wall": time.perf_counter, "cpu": time.process_time}

WARMUP = 3
"""Sequences rendered both ways before measuring (indices 10,000 and up: not measured ones)."""


def paired_parser(name: str, description: str, samples: int, set_example: str) -> argparse.ArgumentParser:
    """The command line every paired cost benchmark shares (``python -m benchmarks.<name>``): ``--config``,
    ``--set`` (repeatable), ``--size HxW``, ``--samples``; parsing it runs nothing."""
    parser = argparse.ArgumentParser(prog=f"python -m benchmarks.{name}", description=description)
    parser.add_argument("--config", default=DEFAULT_PRESET, help=f"preset name or YAML path (default {DEFAULT_PRESET})")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help=f"override a config field (repeatable), e.g. --set {set_example}")
    parser.add_argument("--size", type=parse_size, default=(384, 512), metavar="HxW", help="image size (default 384x512)")
    parser.add_argument("--samples", type=int, default=samples, help="measured sequences (after 3 warm-up ones)")
    return parser


def paired_config(name: str, args: argparse.Namespace) -> SidarConfig:
    """The config a :func:`paired_parser` command line asks for; a wrong field or value stops the
    command with a message naming it."""
    try:
        return load_config(args.config, image_size=args.size, **parse_set(args.set))
    except (ValueError, FileNotFoundError) as error:
        raise SystemExit(f"{name}: {error}") from error


def paired_settings_times(config: Any, off: Any, on: Any, samples: int,
                          differences: Any = None) -> tuple[dict, list[tuple[dict, dict]]]:
    """Render ``samples`` sequences of ``config`` with the ``RenderSettings`` ``off`` and ``on``.

    Args:
        differences: if given, its ``append`` gets each measured sequence's ``(V, H, W, 3)`` int16
            difference of the views, ``on`` minus ``off`` (8-bit sRGB levels; e.g.
            ``setting_cost.ViewDifference``, which keeps a summary).

    Returns:
        ms per view keyed ``(clock, on)`` (``on`` False for ``off``; lists in sample order), and each
        measured sequence's ``(timings off, timings on)`` step dicts (seconds, see ``SceneRenderer.render``).
    """
    from sidar_torch.render import shared_renderer  # imports pyrender: here, so parsing loads no GL

    dataset = SidarDataset(config=config, seed=0)
    renderers = {False: shared_renderer(off), True: shared_renderer(on)}
    ms_per_view: dict[tuple[str, bool], list[float]] = {(clock, on): [] for clock in CLOCKS for on in (False, True)}
    steps: list[tuple[dict, dict]] = []
    warmup = [10_000 + k for k in range(WARMUP)]
    for index in warmup + list(range(samples)):
        sequence = dataset.scene(index)
        painting = dataset.source.painting(index % len(dataset.source), config.image_size)
        pair: dict[bool, dict[str, float]] = {}
        views: dict[bool, np.ndarray] = {}
        for on in ((False, True) if index % 2 else (True, False)):
            start = {clock: read() for clock, read in CLOCKS.items()}
            with collect_timings() as pair[on]:
                views[on] = renderers[on].render(sequence, painting).views
            if index in warmup:
                continue
            for clock, read in CLOCKS.items():
                ms_per_view[clock, on].append(1e3 * (read() - start[clock]) / len(sequence.views))
        if index not in warmup:
            steps.append((pair[False], pair[True]))
            if differences is not None:
                differences.append(views[True].astype(np.int16) - views[False])
    return ms_per_view, steps


def print_paired(ms_per_view: dict, labels: tuple[str, str]) -> None:
    """One line per clock: the medians of the two ways (``labels``: off, on), and the median paired
    difference (same sequence, on minus off; steadier on a loaded machine)."""
    for clock in CLOCKS:
        without, with_ = (statistics.median(ms_per_view[clock, on]) for on in (False, True))
        paired = statistics.median(b - a for a, b in zip(ms_per_view[clock, False], ms_per_view[clock, True]))
        print(f"{clock:>4}: median ms / view {labels[0]} {without:.1f}, {labels[1]} {with_:.1f}; "
              f"median paired difference {paired:+.2f} ms ({100 * paired / without:+.1f} %)")
