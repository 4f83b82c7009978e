"""Rendering on a Ray cluster: a lazy ``ray.data`` dataset of samples, and a distributed export.

Ray is an optional dependency (``pip install "ray[data]>=2.9"``, the ``sidar_torch[ray]`` extra):
importing this module needs no Ray; each function imports it when called and raises ``ImportError``
saying how to install it if it is missing.

* :func:`ray_dataset`: a ``ray.data.Dataset`` with one row per dataset index, rendered by a pool
  of Ray actors (``map_batches``), to stream into training without writing files;
  :func:`torch_batches` iterates it as batches of the tensors :class:`~sidar_torch.SidarDataset` hands out.
* :func:`ray_export`: :func:`~sidar_torch.export_dataset` with Ray tasks rendering and writing:
  the same files, the same resumption.

Same bytes as one machine: a Ray worker renders index ``i`` with :meth:`SidarDataset.sample_arrays`
(a pure function of ``(seed, i)``), so rows and files do not depend on the number of nodes,
actors or retries, given the same rasteriser on every node (llvmpipe, the OSMesa/EGL CPU path,
gives the bytes of this machine; a GPU driver gives other, equally valid pixels).

Ray workers: every actor or task takes one CPU (``num_cpus=1``): llvmpipe rasterises in the calling
thread (``LP_NUM_THREADS=0``, set by ``import sidar_torch``) and torch works on one thread there
(Ray sets ``OMP_NUM_THREADS=1``). A worker process keeps its renderer (GL context, compiled
shaders: about a second to make) for all the batches or tasks it runs, in itself: it forks no process
that renders (``render.context.forks_nothing``), so it renders with Mesa's disk cache and needs no render
process. The GL platform is the
worker's ``PYOPENGL_PLATFORM`` (default ``osmesa``); a local cluster inherits the driver's
environment, a remote one takes it from ``ray.init(runtime_env={"env_vars": {"PYOPENGL_PLATFORM":
"egl"}})`` (GPU nodes) or the nodes' own environment. Every node needs ``sidar_torch`` and the GL
libraries installed, and an image-folder source must be readable at the same path on every node.
"""

from __future__ import annotations

import math
import os
import sys
import time
from pathlib import Path
from types import ModuleType
from typing import Any, Iterator

import numpy as np
import torch

from ..config import as_int
from ..data.dataset import SidarDataset
from . import ExportPlan, ExportSummary, Layout, Progress, WriteUnit, either_shard_size, planned_export
from ..orphans import ProcessStamp, exit_with_process
from ..render.context import forks_nothing
from ..sample import KEYS, SampleArrays, stack_arrays

__all__ = ["ray_dataset", "ray_export", "torch_batch", "torch_batches"]

RAY_REQUIREMENT = "ray[data]>=2.9"
"""What the ``ray`` extra of ``pyproject.toml`` installs (a test keeps them equal)."""

INSTALL_HINT = f'Ray is not installed: pip install "{RAY_REQUIREMENT}"'

MAX_INDEX_BLOCKS = 10_000
""":func:`ray_dataset`: most blocks the indices are cut into (each an object the driver puts in Ray's store)."""


def _ray() -> ModuleType:
    """The ``ray`` module with ``ray.data`` loaded, or ``ImportError`` with the install hint."""
    try:
        import ray
        import ray.data
    except ImportError as error:
        raise ImportError(INSTALL_HINT) from error
    return ray


def _connect(ray: ModuleType, address: str | None) -> bool:
    """Join the cluster at ``address`` (``None``: ``RAY_ADDRESS`` if set, else a new local cluster of
    this machine's CPUs) unless this process already called ``ray.init``; True if this call started Ray."""
    if ray.is_initialized():
        if address is not None:
            raise ValueError(f"address: Ray is already initialised in this process, so {address!r} cannot be "
                             f"joined; pass address=None to use the running cluster")
        return False
    ray.init(address=address)
    return True


def _check_address(address: Any) -> str | None:
    if address is not None and (not isinstance(address, str) or not address):
        raise TypeError(f"address: expected a Ray address such as 'auto' or 'ray://head:10001', or None, "
                        f"got {address!r}")
    return address


# --------------------------------------------------------------------------- streaming


def _columns(samples: list[SampleArrays]) -> dict[str, np.ndarray]:
    """Samples -> a batch of columns: every :data:`~sidar_torch.sample.KEYS` field the samples hold,
    stacked (``images`` ``(B, V, H, W, 3)`` uint8, ..., ``homography_error`` ``(B,)`` float64,
    ``index`` ``(B,)`` int64)."""
    return {key.name: np.stack([getattr(s, key.name) for s in samples]) for key in KEYS
            if getattr(samples[0], key.name) is not None}


class _Renderer:
    """``map_batches`` class: one instance per Ray actor, for the actor's life; the renderer it uses
    is the actor process's own (``SidarDataset.renderer``), made at its first sample and reused."""

    def __init__(self, dataset: SidarDataset):
        forks_nothing()  # a Ray worker renders in itself, with Mesa's disk cache: it forks no renderer
        self.dataset = dataset

    def __call__(self, batch: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        return _columns([self.dataset.sample_arrays(int(index)) for index in batch["data"]])


def _index_blocks(ray: ModuleType, start: int, count: int, batch_size: int) -> Any:
    """A ``ray.data.Dataset`` of the indices (column ``data``, int64) in blocks of about ``batch_size``
    (at most :data:`MAX_INDEX_BLOCKS` blocks). Made here and put in the object store, not read by a
    Ray task: a read task needs a CPU, which a pool of one actor per CPU never frees (Ray Data then
    waits for ever)."""
    blocks = min(math.ceil(count / batch_size), MAX_INDEX_BLOCKS)
    return ray.data.from_numpy(np.array_split(np.arange(start, start + count, dtype=np.int64), blocks))


def ray_dataset(dataset: SidarDataset, count: int, start: int = 0, actors: int = 2, batch_size: int = 1,
                address: str | None = None) -> Any:
    """Samples ``start .. start + count - 1`` of ``dataset`` as a lazy ``ray.data.Dataset``, rendered
    by a pool of ``actors`` Ray actors of one CPU each when it is consumed.

    One row per index, with the :class:`~sidar_torch.sample.SampleArrays` fields as columns
    (``V`` views of ``H x W``): ``images`` ``(V, H, W, 3)`` uint8, ``masks`` ``(V, H, W)`` uint8 (255 where
    the painting is not visible), each optional output switched on (``choices.outputs.OUTPUTS``: ``(V, H, W)``
    or ``(V, H, W, C)`` of its row's dtype, as :class:`~sidar_torch.sample.SampleArrays` holds it), ``label``
    ``(H, W, 3)`` uint8, ``homographies`` ``(V, V, 3, 3)`` float64, ``homography_error``
    float64 (pixels), ``K``, ``R`` ``(V, 3, 3)`` and ``t`` ``(V, 3)`` float64 (OpenCV camera frame),
    ``index`` int64. 8-bit pixels cross the cluster at a quarter of the size of float32 views. Row
    ``i`` is byte for byte ``dataset.sample_arrays(i)`` (``SampleArrays(**row)`` rebuilds it);
    :func:`torch_batches` iterates batches of the tensors of ``dataset.sample``. Rows arrive in any
    order (Ray Data does not keep it unless ``DataContext.get_current().execution_options.preserve_order``
    is set): use ``index``.

    Args:
        dataset: the :class:`SidarDataset` to render (pickled to every actor).
        count: number of samples, ``>= 1``.
        start: first dataset index, ``>= 0``.
        actors: size of the actor pool, ``>= 1``; each actor makes its renderer once.
        batch_size: samples per ``map_batches`` call, ``>= 1``.
        address: the cluster to join if this process has not called ``ray.init``: ``None`` joins
            ``RAY_ADDRESS`` if set, else starts a local cluster; ``"auto"``, ``"HOST:PORT"`` or
            ``"ray://HOST:10001"`` name one.

    Raises:
        ImportError: Ray is not installed (the message says how to install it).
        TypeError: ``dataset`` is not a :class:`SidarDataset`, or a bad ``address``.
        ValueError: a bad ``count``, ``start``, ``actors`` or ``batch_size``; ``address`` given
            while Ray is already initialised.
    """
    ray = _ray()
    if not isinstance(dataset, SidarDataset):
        raise TypeError(f"dataset: expected a SidarDataset, got {type(dataset).__name__}")
    count, start = as_int("count", count, 1), as_int("start", start, 0)
    actors, batch_size = as_int("actors", actors, 1), as_int("batch_size", batch_size, 1)
    _connect(ray, _check_address(address))
    return _index_blocks(ray, start, count, batch_size).map_batches(
        _Renderer, fn_constructor_args=(dataset,), batch_size=batch_size, num_cpus=1,
        compute=ray.data.ActorPoolStrategy(size=actors), batch_format="numpy")


def torch_batch(batch: dict[str, np.ndarray], geometry_dtype: str = "float32") -> dict[str, torch.Tensor]:
    """A batch of :func:`ray_dataset` rows (a dict of NumPy columns) -> the batch of their samples as
    :class:`SidarDataset` makes them: :meth:`SampleArrays.to_tensors` of each row, stacked as
    :func:`~sidar_torch.sample.stack_samples` stacks them (by :func:`~sidar_torch.sample.stack_arrays`;
    ``images`` ``(B, V, 3, H, W)`` float32 in [0, 1], ...,
    homographies and cameras in ``geometry_dtype``, ``homography_error`` ``(B,)`` float64,
    ``index`` ``(B,)`` int64)."""
    # Copies: Ray hands out read-only arrays, which torch.from_numpy would wrap as they are.
    rows = [SampleArrays(**{name: np.array(column[b]) for name, column in batch.items()})
            for b in range(len(batch["index"]))]
    return stack_arrays(rows, geometry_dtype)


def torch_batches(rows: Any, batch_size: int, geometry_dtype: str = "float32",
                  **iter_batches_options: Any) -> Iterator[dict[str, torch.Tensor]]:
    """Iterate a :func:`ray_dataset` (or a Ray Train dataset shard of one) as batches of tensors:
    ``rows.iter_batches(batch_size=batch_size, batch_format="numpy", **iter_batches_options)``
    through :func:`torch_batch`. Pass ``dataset.config.geometry_dtype`` for a float64 config.
    (Ray's ``iter_torch_batches`` would convert the 8-bit columns as they are, not as
    :class:`SidarDataset` does.)"""
    batch_size = as_int("batch_size", batch_size, 1)
    for batch in rows.iter_batches(batch_size=batch_size, batch_format="numpy", **iter_batches_options):
        yield torch_batch(batch, geometry_dtype)


# --------------------------------------------------------------------------- export


def _write(dataset: SidarDataset, out: Path, layout: Layout, units: list[WriteUnit],
           driver: ProcessStamp) -> tuple[int, float]:
    """Ray task: render and write ``units`` of ``layout`` into ``out``; returns how many sequences
    the units add and the seconds it took.

    Safe to run again after an attempt died part-way (Ray retries a task whose worker died): the
    layout keeps what ``out`` holds and writes only what is missing (see :meth:`.io.Layout.write`),
    as a local rerun does; the driver holds the export's lock, so no one else writes there."""
    exit_with_process(driver)  # Ray ends a dead driver's tasks only 2-5 s later
    forks_nothing()  # a Ray worker renders in itself, with Mesa's disk cache: it forks no renderer
    begin = time.perf_counter()
    for unit in units:
        layout.write(out, unit, dataset.sample_arrays, lambda: None)
    return sum(len(unit.indices) for unit in units), time.perf_counter() - begin


def _tasks(units: list[WriteUnit], units_per_task: int, cpus: int) -> list[list[WriteUnit]]:
    """``units`` cut into runs of consecutive units, at least 4 per CPU when there are enough units
    and at most ``units_per_task`` units each (the layout's :attr:`~.io.Layout.units_per_task`)."""
    size = max(1, min(units_per_task, math.ceil(len(units) / (4 * max(cpus, 1)))))
    return [units[k:k + size] for k in range(0, len(units), size)]


def ray_export(dataset: SidarDataset, out_dir: str | os.PathLike, count: int, start: int = 0,
               shard_size: int | None = None, address: str | None = None, progress: bool = True, *,
               shards: int | None = None) -> ExportSummary:
    """:func:`~sidar_torch.export_dataset` on a Ray cluster: the same files, byte for byte.

    This process checks the arguments, holds the export's lock, writes the manifest and finds what
    is missing, exactly as :func:`export_dataset` does; then Ray tasks of one CPU render and write
    straight into ``out_dir``: one task per tar shard (``shard_size=N``), or per run of up to
    16 sequence folders (the layout's ``units_per_task``). So ``out_dir`` must be the same shared folder
    on every node (a local cluster: any folder). Resumption is the local export's: each folder or
    shard appears complete or not at all, a rerun renders only what is missing; a task whose
    worker dies is retried by Ray (up to 3 times) without writing anything twice. If this process
    dies, its tasks on this machine end within a tenth of a second (Ray ends the others); rerun
    the same call. Nothing is rendered, and Ray is not started, when every sequence is already there
    and no shard is damaged.

    Args:
        dataset, out_dir, count, start, shard_size, progress, shards: as for :func:`export_dataset`
            (the progress line counts finished tasks' sequences).
        address: the cluster to join if this process has not called ``ray.init`` (see
            :func:`ray_dataset`); a cluster this call starts is shut down at its end.

    Returns:
        An :class:`~sidar_torch.io.ExportSummary`.

    Raises:
        ImportError: Ray is not installed (the message says how to install it).
        TypeError, ValueError, RuntimeError, ExportInterrupted: as :func:`export_dataset`; a bad ``address``.
    """
    ray = _ray()
    address = _check_address(address)
    begin = time.perf_counter()
    with planned_export(dataset, out_dir, count, start, either_shard_size(shard_size, shards)) as plan:
        if plan.missing or plan.damaged:
            started = _connect(ray, address)
            try:
                _run_tasks(ray, dataset, plan, progress)
            finally:
                if started:
                    ray.shutdown()
    return ExportSummary(plan.out, tuple(plan.missing), len(plan.present), time.perf_counter() - begin)


def _run_tasks(ray: ModuleType, dataset: SidarDataset, plan: ExportPlan, progress: bool) -> None:
    """Submit the tasks writing ``plan.missing`` and wait for all, advancing the progress line by
    each finished task's sequences and busy time; if one fails (or this process is interrupted),
    the others are cancelled before the lock is released."""
    cpus = int(ray.cluster_resources().get("CPU", 1))
    jobs = _tasks(plan.units(), plan.layout.units_per_task, cpus)
    task = ray.remote(_write).options(num_cpus=1, max_retries=3)
    dataset_ref, out, driver = ray.put(dataset), plan.out.absolute(), ProcessStamp.this_process()
    pending = [task.remote(dataset_ref, out, plan.layout, job, driver) for job in jobs]
    with Progress(len(plan.missing), sys.stderr if progress else None) as bar:
        try:
            while pending:
                done, pending = ray.wait(pending, num_returns=1)
                count, seconds = ray.get(done[0])
                bar.advance(count, busy=seconds, parallel=min(cpus, len(pending)))
        except BaseException:
            for ref in pending:
                ray.cancel(ref, force=True)
            raise
