"""What every measurement shares: the clock, medians, sizes, one thread, the machine, the kornia baseline.

* Per-core figures are **process CPU time** (:func:`cpu_seconds`, ``time.process_time``): with torch
  on one thread (:func:`one_thread`) and llvmpipe rasterising in the calling thread
  (``LP_NUM_THREADS=0``, which ``import sidar_torch`` sets unless the environment says otherwise),
  this process uses one core, and other jobs sharing the machine change its CPU time far less than
  its wall time. Throughput across processes (DataLoader workers) is wall time.
* Sizes are ``(H, W)`` pixels everywhere, written ``HxW`` on the command line and in tables
  (``384x512`` is 384 rows by 512 columns); :func:`parse_size` reads them, :func:`size_label`
  writes them.
* Ratios to kornia are always to a baseline run in the same process (:func:`kornia_call`), its calls
  timed in between the calls it is compared with.
* Fresh memory costs page faults, counted in CPU time, and under glibc's defaults a process's
  history decides which allocations fault; :func:`warm_heap` puts the heap where none does.
"""

from __future__ import annotations

import argparse
import contextlib
import ctypes
import ctypes.util
import os
import platform
import statistics
import time
from typing import Callable, Iterable, Iterator

import torch

from sidar_torch.cli import parse_overrides as parse_set

__all__ = ["DEFAULT_PRESET", "cpu_seconds", "kornia_call", "kornia_pipeline", "machine", "machine_line",
           "median", "plain_pipeline", "warm_heap", "one_thread", "parse_set", "parse_size", "rss_mb", "size_label"]

DEFAULT_PRESET = "misaligned"
"""The preset ``SidarDataset`` uses when given none; the speed targets refer to it."""


def cpu_seconds(call: Callable[[], object]) -> float:
    """Process CPU time of one ``call()``, seconds (every thread of this process, no child)."""
    start = time.process_time()
    call()
    return time.process_time() - start


_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3
"""glibc's ``mallopt`` parameters (``malloc.h``)."""

WARM_HEAP_MIB = 1024
"""What :func:`warm_heap` faults in and keeps, MiB."""


def warm_heap() -> bool:
    """Put this process's heap in the state of a long run (glibc only; for the rest of the process).

    Blocks up to 32 MiB (glibc's largest mmap threshold) come from the heap, freed memory is never
    returned to the system, and :data:`WARM_HEAP_MIB` are faulted in and freed now: a call that
    allocates afterwards reuses touched pages instead of faulting fresh ones in. Under glibc's
    defaults whether it does depends on what the process allocated before (in the bench, kornia's
    batched pipeline cost 11.3-11.9 ms per image timed in a block of its own calls, 6.8-7.2 ms timed
    between ``SidarAugment``'s calls; docs/speed.md), which no two benchmarks share.

    Returns:
        Whether it applied (False without glibc's ``mallopt``).
    """
    name = ctypes.util.find_library("c")
    mallopt = getattr(ctypes.CDLL(name), "mallopt", None) if name else None
    if mallopt is None or not (mallopt(_M_MMAP_THRESHOLD, 32 << 20) and mallopt(_M_TRIM_THRESHOLD, 2**31 - 1)):
        return False
    blocks = [bytearray(16 << 20) for _ in range(WARM_HEAP_MIB // 16)]  # zero-filled: every page touched
    del blocks
    return True


def median(values: Iterable[float]) -> float:
    """Median of ``values`` (at least one)."""
    return statistics.median(list(values))


@contextlib.contextmanager
def one_thread() -> Iterator[None]:
    """Torch on one thread inside the block (as in DataLoader workers), restored after it.

    The only place the measurements change torch's process-wide thread count."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        yield
    finally:
        torch.set_num_threads(threads)


def parse_size(text: str) -> tuple[int, int]:
    """``HEIGHTxWIDTH`` (``384x512``) -> ``(384, 512)``; raises ``argparse.ArgumentTypeError`` otherwise."""
    h, sep, w = str(text).lower().partition("x")
    try:
        size = (int(h), int(w)) if sep else (0, 0)
    except ValueError:
        size = (0, 0)
    if min(size) < 1:
        raise argparse.ArgumentTypeError(f"size {text!r}: expected HEIGHTxWIDTH in pixels, e.g. 384x512")
    return size


def size_label(size: tuple[int, int]) -> str:
    """``(H, W)`` -> ``"HxW"``, e.g. ``"384x512"``."""
    return f"{size[0]}x{size[1]}"


def rss_mb() -> float:
    """Resident memory of this process now, MiB (``/proc/self/statm``; ``nan`` without it)."""
    try:
        with open("/proc/self/statm") as statm:
            return int(statm.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20
    except (OSError, ValueError):
        return float("nan")


def machine() -> dict[str, object]:
    """Cores, load average (1 minute), versions, GL platform and llvmpipe threads of this machine now."""
    import kornia

    from sidar_torch.render.context import GL_PLATFORM

    return {"cpus": os.cpu_count(), "load": os.getloadavg()[0], "python": platform.python_version(),
            "torch": torch.__version__, "kornia": kornia.__version__, "gl_platform": GL_PLATFORM,
            "lp_num_threads": os.environ.get("LP_NUM_THREADS")}


def machine_line(before: dict[str, object], after: dict[str, object]) -> str:
    """One line describing the machine, with the load average before and after a run."""
    loaded = max(before["load"], after["load"]) > 0.5 * (before["cpus"] or 1)
    return (f"{before['cpus']} cores, load average {before['load']:.2f} at start, {after['load']:.2f} at end"
            f"{' (other jobs ran: wall-clock figures are pessimistic, CPU-time figures less so)' if loaded else ''}; "
            f"Python {before['python']}, torch {before['torch']} (1 thread), kornia {before['kornia']}, "
            f"GL {before['gl_platform']}, LP_NUM_THREADS={before['lp_num_threads']}")


def kornia_pipeline() -> torch.nn.Module:
    """Kornia's 2-D augmentation pipeline the speed targets compare with: RandomPerspective(0.5) +
    ColorJitter(0.2, 0.2, 0.2, 0.05) + RandomPlasmaShadow + RandomGaussianNoise(std 0.05), each
    applied with probability 1."""
    import kornia.augmentation as KA

    return torch.nn.Sequential(
        KA.RandomPerspective(0.5, p=1.0), KA.ColorJitter(0.2, 0.2, 0.2, 0.05, p=1.0),
        KA.RandomPlasmaShadow(p=1.0), KA.RandomGaussianNoise(std=0.05, p=1.0))


def plain_pipeline() -> torch.nn.Module:
    """The first two steps of :func:`kornia_pipeline` alone: RandomPerspective(0.5) + ColorJitter(0.2,
    0.2, 0.2, 0.05), each applied with probability 1 (a plain geometric and photometric augmentation)."""
    return torch.nn.Sequential(*list(kornia_pipeline())[:2])


def kornia_call(batch: int, size: tuple[int, int], seed: int = 0,
                pipeline: Callable[[], torch.nn.Module] = kornia_pipeline) -> Callable[[], object]:
    """One call of ``pipeline()`` (default :func:`kornia_pipeline`) on a ``(batch, 3, H, W)`` float32
    batch, as a function to time (one untimed call made here). Benchmarks time its calls between their
    own, so that the baseline and what it is compared with meet the same state of the machine."""
    torch.manual_seed(seed)
    module = pipeline()
    images = torch.rand(batch, 3, *size)

    def call() -> object:
        with torch.no_grad():
            return module(images)

    call()
    return call
