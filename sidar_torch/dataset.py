"""``SidarDataset``: paintings x random scenes x renderer -> samples of tensors, on the fly.

A sample is a pure function of ``(seed, index)``: its scene, then its view effects (if any are
switched on, see ``sidar_torch.artifacts``), are drawn with ``numpy.random.default_rng([seed,
index])`` and its painting is ``source[index % len(source)]``,
so the same sample comes out whatever the number of workers, ranks or the order of iteration.
"""

from __future__ import annotations

import os
from typing import Any, Iterator

import numpy as np
import torch
from torch.utils.data import IterableDataset, get_worker_info

from . import geometry
from .artifacts import apply_effects, draw_effects
from .config import SidarConfig, load_config
from .render import RenderSettings, shared_renderer
from .scene import SceneSequence, sample_sequence
from .sources import PaintingSource, make_source
from .timing import timed

__all__ = ["SidarDataset", "render_sample", "sequence_homographies"]


def sequence_homographies(sequence: SceneSequence) -> tuple[torch.Tensor, float]:
    """Every pairwise homography of a sequence and a bound on its error.

    Four points of the painting's plane in front of every camera (:func:`sidar_torch.geometry.fit_points`)
    are projected with each camera in float64 and Kornia's DLT fits every ordered pair (see
    :func:`sidar_torch.geometry.homographies_from_points`).

    Returns:
        ``(V, V, 3, 3)`` float64 homographies (det = 1), and the largest distance in view-j pixels
        between where they and the analytic plane-induced homographies send the painting points
        both views of a pair see (a 17 x 17 lattice, :func:`sidar_torch.geometry.visible_plane_points`):
        the DLT is exact at its own four points, so the error shows elsewhere.
    """
    K, R, t = sequence.cameras()
    centres = np.stack([view.camera.position for view in sequence.views])
    H = geometry.homographies_from_points(geometry.project(K, R, t, geometry.fit_points(centres)))
    pixels, inside = geometry.visible_plane_points(K, R, t, sequence.image_size)
    truth = geometry.plane_induced_homographies(K, R, t)
    return H, geometry.point_disagreement(H.numpy(), truth, pixels, geometry.shared_points(inside))


def render_sample(sequence: SceneSequence, painting: np.ndarray, config: SidarConfig, index: int,
                  timings: dict[str, float] | None = None, rng: np.random.Generator | None = None) -> dict[str, Any]:
    """Render ``sequence`` with ``painting`` and assemble one sample dict (see :class:`SidarDataset`).

    The one place where a sample is put together: :meth:`SidarDataset.sample` and
    :class:`sidar_torch.SidarAugment` both call it.

    Args:
        sequence: the scenes (``sequence.image_size`` must be ``config.image_size``).
        painting: ``(H, W, 3)`` uint8 RGB, the texture, already fitted to ``config.image_size``.
        config: gives the renderer's settings (image size, shadow-map size and filter,
            ``opacity_output``) and the view effects (:mod:`sidar_torch.artifacts`: background,
            exposure, noise, JPEG; off by default).
        index: stored as the sample's ``index``.
        timings: if given, seconds spent are added to its keys: the renderer's steps (see
            :meth:`sidar_torch.render.SceneRenderer.render`), ``"effects"`` (the view effects, when
            any is on), ``"homographies"`` and ``"tensors"`` (conversion of the pixels to float tensors).
        rng: the generator that drew ``sequence``; the view effects draw from it next. Needed only
            when ``config`` switches an effect on (``ValueError`` otherwise).

    Returns:
        The sample dict of CPU tensors (``images``, ``masks``, ``opacities`` if
        ``config.opacity_output``, ``label``, ``homographies``, ``K``, ``R``, ``t`` float32),
        ``homography_error`` (float) and ``index`` (int).
    """
    effects = draw_effects(config, len(sequence.views), sequence.image_size, rng)
    rendered = shared_renderer(RenderSettings.from_config(config)).render(sequence, painting, timings)
    K, R, t = sequence.cameras()
    views = rendered.views
    if effects is not None:
        with timed(timings, "effects"):
            views = apply_effects(views, rendered.background, effects)
    with timed(timings, "homographies"):
        homographies, homography_error = sequence_homographies(sequence)
    with timed(timings, "tensors"):
        return {
            "images": torch.from_numpy(views).permute(0, 3, 1, 2).float().div_(255),
            "masks": torch.from_numpy(rendered.masks).unsqueeze(1).float(),
            **({} if rendered.opacities is None else
               {"opacities": torch.from_numpy(rendered.opacities).unsqueeze(1).float().div_(255)}),
            "label": torch.from_numpy(rendered.label).permute(2, 0, 1).float().div_(255),
            "homographies": homographies.float(),
            "homography_error": homography_error,
            "K": torch.from_numpy(K).float(),
            "R": torch.from_numpy(R).float(),
            "t": torch.from_numpy(t).float(),
            "index": index,
        }


def _check_int(name: str, value: Any, low: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
        raise ValueError(f"{name}: expected an integer >= {low}, got {value!r}")
    return int(value)


def _process_group_rank() -> tuple[int, int] | None:
    """``(rank, world_size)`` from ``torch.distributed`` if its process group is initialised, else None."""
    if torch.distributed.is_available() and torch.distributed.is_initialized():
        return torch.distributed.get_rank(), torch.distributed.get_world_size()
    return None


class SidarDataset(IterableDataset):
    """SIDAR sequences rendered on the fly, for ``torch.utils.data.DataLoader``.

    Args:
        source: the paintings: ``None`` (built-in procedural paintings), a folder, an image path
            or list of paths, a tensor ``(N, 3, h, w)`` / ``(3, h, w)``, a sequence of tensors or
            PIL images, or any indexable dataset of images (see ``sidar_torch.sources``). Images that
            cannot be read raise or are skipped as ``config.on_bad_image`` says.
        config: a :class:`SidarConfig`, a preset name or a YAML path (default ``"misaligned"``).
        seed: the dataset's seed (integer >= 0).
        length: ``None`` for an endless stream, or ``N``: indices ``0..N-1``, each exactly once
            across all DataLoader workers and distributed ranks.
        crop: how paintings are fitted to the output aspect, ``"center"`` or ``"none"``.

    Each sample is a dict (``V`` views of ``H x W`` pixels):

    - ``images`` ``(V, 3, H, W)`` float32 in [0, 1]: the views; view 0 is the reference camera.
    - ``masks`` ``(V, 1, H, W)`` float32 in {0, 1}: 1 where the painting is not visible.
    - ``opacities`` ``(V, 1, H, W)`` float32 in [0, 1], only with ``config.opacity_output``: the
      fraction of the painting hidden at each pixel, a soft ``masks``: 1 off the painting and
      behind opaque occluders, 0 where the painting is seen unobstructed, and
      ``1 - prod_k (1 - a_k)`` where transparent occluders ``k`` cover it, ``a_k`` the opacity
      the view blends them with (material alpha raised by Fresnel towards grazing views; their
      highlights, which also hide the painting in ``images``, are left out). Every visible
      occluder counts, whatever ``mask_min_opacity`` is; values are multiples of 1/255.
    - ``label`` ``(3, H, W)`` float32 in [0, 1]: the painting in view 0's frame, unlit, unoccluded.
    - ``homographies`` ``(V, V, 3, 3)`` float32: ``H[i, j]`` maps view-i pixels to view-j pixels
      (Kornia convention, det = 1).
    - ``K``, ``R`` ``(V, 3, 3)`` and ``t`` ``(V, 3)`` float32: intrinsics in pixels and
      world-to-camera pose (OpenCV frame); world point ``X`` lands at ``K (R X + t)``.
    - ``homography_error`` float: largest disagreement, in pixels at the four fitted points, between
      the float64 homographies (Kornia DLT) and the analytic plane-induced ones.
    - ``index`` int: the sample's index.

    Rendering uses this process's shared renderer (``sidar_torch.render.shared_renderer``),
    created at the first sample: each DataLoader worker makes its own and reuses it.

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
    """

    def __init__(self, source: Any = None, config: SidarConfig | str | os.PathLike | None = None,
                 seed: int = 0, length: int | None = None, crop: str = "center"):
        super().__init__()
        if not isinstance(config, (SidarConfig, str, os.PathLike, type(None))):
            raise TypeError(f"config: expected a SidarConfig, preset name or YAML path, got {type(config).__name__}")
        self.config = load_config(config if config is not None else "misaligned")
        self.source: PaintingSource = make_source(source, crop=crop, on_bad_image=self.config.on_bad_image)
        self.seed = _check_int("seed", seed, 0)
        self.length = None if length is None else _check_int("length", length, 1)

    def __len__(self) -> int:
        if self.length is None:
            raise TypeError("SidarDataset is an endless stream (length=None) and has no len()")
        return self.length

    def generator(self, index: int) -> np.random.Generator:
        """A fresh copy of sample ``index``'s generator, ``numpy.random.default_rng([seed, index])``:
        the scene sampler draws from it first, then the view effects."""
        return np.random.default_rng([self.seed, _check_int("index", index, 0)])

    def scene(self, index: int) -> SceneSequence:
        """The scene description of sample ``index`` (no rendering)."""
        return sample_sequence(self.config, self.generator(index))

    def sample(self, index: int) -> dict[str, Any]:
        """Render sample ``index`` (a pure function of ``(seed, index)``); see the class docstring."""
        rng = self.generator(index)
        sequence = sample_sequence(self.config, rng)
        painting = self.source.painting(index % len(self.source), self.config.image_size)
        return render_sample(sequence, painting, self.config, index, rng=rng)

    def indices(self) -> Iterator[int]:
        """The indices this process draws: ``k, k + n, k + 2n, ...`` (below ``length`` if finite)
        for its shard ``k`` of ``n`` (see "Sharding" in the class docstring).

        Raises:
            ValueError: ``RANK``/``WORLD_SIZE`` in the environment are not a valid rank of a world.
        """
        rank, world_size = self._rank_and_world_size()
        info = get_worker_info()
        worker, num_workers = (info.id, info.num_workers) if info is not None else (0, 1)
        index, n_shards = rank * num_workers + worker, world_size * num_workers
        while self.length is None or index < self.length:
            yield index
            index += n_shards

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

    def __iter__(self) -> Iterator[dict[str, Any]]:
        for index in self.indices():
            yield self.sample(index)
