"""``SidarDataset``: paintings x random scenes x renderer -> samples of tensors, on the fly.

A sample is a pure function of ``(seed, index)``: its scene, then its view effects (if any are
switched on, see ``sidar_torch.sample.effects``), are drawn with ``numpy.random.default_rng([seed,
index])`` and its painting is ``source[index % len(source)]``,
so the same sample comes out whatever the number of workers, ranks or the order of iteration.
"""

from __future__ import annotations

import itertools
import os
from typing import TYPE_CHECKING, Any, Iterator

import numpy as np
import torch
from torch.utils.data import IterableDataset, get_worker_info

from ..config import SidarConfig, as_int, load_config
from ..render import RenderSettings, preload, renderer_for
from ..sample import SampleArrays, render_arrays
from ..scene import SceneSequence, sample_sequence
from ..paintings import PaintingSource, make_source
from ..sample.warm_up import announce_compiles, warm_up_renderer

if TYPE_CHECKING:  # the renderer's module imports pyrender: loaded at the first render
    from ..render import RenderProcess, SceneRenderer

__all__ = ["EPOCH_STRIDE", "SidarDataset"]

EPOCH_STRIDE = 2**40
"""Indices between the starts of two epochs of an endless stream (see :meth:`SidarDataset.set_epoch`)."""


def _process_group_rank() -> tuple[int, int] | None:
    """``(rank, world_size)`` from ``torch.distributed`` if its process group is initialised, else None."""
    if torch.distributed.is_available() and torch.distributed.is_initialized():
        return torch.distributed.get_rank(), torch.distributed.get_world_size()
    return None


class SidarDataset(IterableDataset):
    """SIDAR sequences rendered on the fly, for ``torch.utils.data.DataLoader``.

    Args:
        source: the paintings: ``None`` (built-in procedural paintings), a folder, an image path
            or list of paths, a tensor ``(N, 3, h, w)`` / ``(3, h, w)``, a NumPy array ``(N, h, w, 3)`` /
            ``(h, w, 3)`` / ``(h, w)`` (channels last, as OpenCV and albumentations give them), a
            sequence of tensors, NumPy images or PIL images, or any indexable dataset of images (see
            ``sidar_torch.paintings``); uint8, or float in [0, 1]. Images that
            cannot be read, or whose files claim more than ``config.max_image_pixels`` pixels, raise or
            are skipped as ``config.on_bad_image`` says; with ``"skip"``, call ``ds.source.scan()``
            once before iterating to drop them up front (see ``sidar_torch.paintings``, "Bad input").
        config: a :class:`SidarConfig`, a preset name or a YAML path (default ``"misaligned"``).
        seed: the dataset's seed (integer >= 0).
        length: ``None`` for an endless stream, or ``N``: indices ``0..N-1``, each exactly once
            across all DataLoader workers and distributed ranks.
        crop: how paintings are fitted to the output aspect, ``"center"`` or ``"none"``.

    Each sample is a dict of CPU tensors and numbers: the views, their occlusion masks, the label,
    every pairwise homography and the cameras. Its keys, with their shapes, dtypes, meanings and
    when each is present, are the table :data:`sidar_torch.sample.KEYS`.

    Rendering uses this process's renderer for the config (:meth:`renderer`), created at the first
    sample and warmed up (every shader variant compiled) by :meth:`warm_up` or before the second
    sample: in the main process a render process holds it (``sidar_torch.render.process``), so the
    main process opens no GL context and forks DataLoader workers safely; each worker makes its own
    and reuses it. Mesa's disk cache keeps the compiled variants for later processes and workers.

    Sharding: the ``num_workers`` DataLoader workers of each of the ``world_size`` ranks split
    the indices into ``n = world_size * num_workers`` shards; worker ``w`` of rank ``r`` draws shard
    ``k = r * num_workers + w``: indices ``k, k + n, k + 2n, ...`` (below ``length`` if finite).
    So no two (rank, worker) pairs draw the same index, and a finite ``length`` is covered exactly
    once. The rank and world size come from ``torch.distributed`` when its process group is
    initialised; else from the rank this dataset was pickled with (a ``spawn``/``forkserver``
    worker of an initialised rank); else from the ``RANK`` and ``WORLD_SIZE`` environment
    variables (``torchrun`` sets them before ``init_process_group``); else rank 0 of 1. Every rank
    must use the same ``num_workers``. Shards differ in size by at most one sample: for equal
    batch counts on every rank under DDP, make ``length`` a multiple of
    ``world_size * num_workers * batch_size``.

    Epochs: :meth:`set_epoch` (the ``DistributedSampler`` habit) moves the stream to fresh indices
    while keeping every sample a pure function of ``(seed, index)`` and the sharding above exact:
    epoch ``e`` draws ``e * N .. e * N + N - 1`` for a finite ``length = N``, and the endless stream
    starts at ``e * EPOCH_STRIDE`` (``2**40``: no epoch reaches the next). Call it before each
    ``iter(loader)``: the epoch lives in a one-element shared-memory tensor that DataLoader workers
    read each time they start an epoch, so it reaches workers that already exist
    (``persistent_workers=True``) as well as fresh ones, under fork, spawn and forkserver. Without it
    every ``iter(loader)`` starts again at the same indices: right for validation, wrong for training.
    """

    def __init__(self, source: Any = None, config: SidarConfig | str | os.PathLike | None = None,
                 seed: int = 0, length: int | None = None, crop: str = "center"):
        super().__init__()
        if not isinstance(config, (SidarConfig, str, os.PathLike, type(None))):
            raise TypeError(f"config: expected a SidarConfig, preset name or YAML path, got {type(config).__name__}")
        self.config = load_config(config if config is not None else "misaligned")
        self.source: PaintingSource = make_source(source, crop=crop, on_bad_image=self.config.on_bad_image,
                                                  max_pixels=self.config.max_image_pixels)
        self.seed = as_int("seed", seed, 0)
        self.length = None if length is None else as_int("length", length, 1)
        self._epoch = torch.zeros((), dtype=torch.int64).share_memory_()
        preload()  # DataLoader workers forked from here inherit the renderer's imports

    @property
    def epoch(self) -> int:
        """The epoch whose indices the next ``iter`` draws (see "Epochs" in the class docstring)."""
        return int(self._epoch)

    def set_epoch(self, epoch: int) -> None:
        """Draw epoch ``epoch``'s indices from the next ``iter(loader)`` on, in this process and in
        every DataLoader worker of this dataset, persistent ones included (see "Epochs" in the class
        docstring)."""
        self._epoch.fill_(as_int("epoch", epoch, 0))

    def __getitem__(self, index: int) -> dict[str, Any]:
        raise TypeError(f"SidarDataset is an IterableDataset and is not indexed: use ds.sample({index!r}) for "
                        f"sample {index!r}, or ExportedDataset for a map-style dataset of a frozen set")

    def __repr__(self) -> str:
        size = "endless" if self.length is None else f"length={self.length}"
        return (f"SidarDataset(source={type(self.source).__name__} of {len(self.source)}, seed={self.seed}, {size}, "
                f"epoch={self.epoch}, image_size={self.config.image_size} (H, W), n_views={self.config.n_views})")

    def __len__(self) -> int:
        if self.length is None:
            raise TypeError("SidarDataset is an endless stream (length=None) and has no len()")
        return self.length

    def generator(self, index: int) -> np.random.Generator:
        """A fresh copy of sample ``index``'s generator, ``numpy.random.default_rng([seed, index])``:
        the scene sampler draws from it first, then the view effects."""
        return np.random.default_rng([self.seed, as_int("index", index, 0)])

    def scene(self, index: int) -> SceneSequence:
        """The scene description of sample ``index`` (no rendering)."""
        return sample_sequence(self.config, self.generator(index))

    def sample(self, index: int) -> dict[str, Any]:
        """Render sample ``index`` (a pure function of ``(seed, index)``): the dict of
        :data:`sidar_torch.sample.KEYS`."""
        return self.sample_arrays(index).to_tensors(self.config.geometry_dtype)

    def sample_arrays(self, index: int) -> SampleArrays:
        """Render sample ``index`` as the arrays :meth:`sample` converts to tensors (8-bit pixels,
        float64 geometry; what export writes)."""
        rng = self.generator(index)
        sequence = sample_sequence(self.config, rng)
        painting = self.source.painting(index % len(self.source), self.config.image_size)
        return render_arrays(self.renderer(), sequence, painting, self.config, index, rng=rng)

    def renderer(self) -> SceneRenderer | RenderProcess:
        """This process's renderer for the config (``sidar_torch.render.renderer_for`` of
        ``RenderSettings.from_config(config)``: a ``RenderProcess`` in a process that may fork, a
        ``SceneRenderer`` in a DataLoader worker), made at the first call, as each sample gets it: warm
        (every shader variant the config can need compiled, ``sidar_torch.sample.warm_up``) after
        :meth:`warm_up`, or else once it has rendered a sample.

        A fresh renderer thus hands its first sample out after compiling (or loading from Mesa's disk
        cache) only the variants that sample draws, and warms up before its second, so its later samples
        still meet no compile mid-stream. Compiling in another order changes no pixel
        (``tests/render/test_warm_up.py``). Before a first sample that will compile because the cache does
        not hold this config's variants yet, it says so once on stderr (``warm_up.announce_compiles``).

        Raises:
            RuntimeError: no GL context can be opened (the message names the package to install).
        """
        renderer = renderer_for(RenderSettings.from_config(self.config))
        if renderer.renders:
            warm_up_renderer(renderer, self.config)
        else:
            announce_compiles(renderer, self.config)
        return renderer

    def indices(self) -> Iterator[int]:
        """The indices this process draws: ``o + k, o + k + n, o + k + 2n, ...`` (``k + ...`` below
        ``length`` if finite) for its shard ``k`` of ``n`` and the offset ``o`` of the epoch current
        at this call (see "Sharding" and "Epochs" in the class docstring).

        Raises:
            ValueError: ``RANK``/``WORLD_SIZE`` in the environment are not a valid rank of a world.
        """
        rank, world_size = self._rank_and_world_size()
        info = get_worker_info()
        worker, num_workers = (info.id, info.num_workers) if info is not None else (0, 1)
        shard, n_shards = rank * num_workers + worker, world_size * num_workers
        if self.length is None:
            return itertools.count(self.epoch * EPOCH_STRIDE + shard, n_shards)
        offset = self.epoch * self.length
        return iter(range(offset + shard, offset + self.length, n_shards))

    def _rank_and_world_size(self) -> tuple[int, int]:
        """``(rank, world_size)`` of this process, from the first of: the initialised process group,
        the rank recorded when this dataset was pickled, ``RANK``/``WORLD_SIZE``, ``(0, 1)``."""
        known = _process_group_rank() or self.__dict__.get("_pickled_rank")
        if known is not None:
            return known
        env_rank, env_world_size = os.environ.get("RANK"), os.environ.get("WORLD_SIZE")
        if env_rank is None and env_world_size is None:
            return 0, 1
        if env_rank is None or env_world_size is None:
            raise ValueError(f"environment: set both RANK and WORLD_SIZE (torchrun does) or neither, got "
                             f"RANK={env_rank!r} WORLD_SIZE={env_world_size!r}")
        try:
            rank, world_size = int(env_rank), int(env_world_size)
        except ValueError:
            raise ValueError(f"environment: expected integers RANK and WORLD_SIZE, got RANK={env_rank!r} "
                             f"WORLD_SIZE={env_world_size!r}") from None
        if not 0 <= rank < world_size:
            raise ValueError(f"environment: expected 0 <= RANK < WORLD_SIZE, got RANK={rank} WORLD_SIZE={world_size}")
        return rank, world_size

    def __getstate__(self) -> dict[str, Any]:
        """Pickled state, with this process's distributed rank: a ``spawn``/``forkserver``
        DataLoader worker unpickles the dataset where no process group is initialised."""
        state = dict(self.__dict__)
        state["_pickled_rank"] = _process_group_rank() or state.get("_pickled_rank")
        return state

    def warm_up(self) -> None:
        """Compile every shader variant this dataset's samples can need in this process's renderer
        (:meth:`renderer`) now (``sidar_torch.sample.warm_up``), which the renderer's second sample does
        otherwise (its first compiles only what it draws); later calls return at once. Called in the main
        process before ``iter(loader)``, it fills Mesa's disk cache with them, from which the DataLoader
        workers forked afterwards load them instead of compiling (where this process renders in itself,
        ``render.render_in_this_process``, forked workers take over its renderer and compile nothing).

        Raises:
            RuntimeError: no GL context can be opened (the message names the package to install).
        """
        warm_up_renderer(self.renderer(), self.config)

    def __iter__(self) -> Iterator[dict[str, Any]]:
        # indices() runs now, not at the first next(): the epoch is the one set before iter().
        return map(self.sample, self.indices())
