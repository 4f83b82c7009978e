"""Views through a lens: how a sequence is rendered through its lenses (:func:`render_through_lens`), the
maps of where each distorted pixel comes from (:func:`distortion_maps`) and the way back for users
(:func:`undistort`). The models and their conventions: :mod:`sidar_torch.choices.lenses`.

How a view is distorted, exactly. Each distorted pixel takes its colour from where the pinhole
camera sees the same ray, which may lie outside the pinhole view (barrel distortion sees more than
the view's pinhole field). So each view is drawn once over the wider undistorted *canvas* that holds
every pixel its bilinear resampling reads (:func:`lens_canvas`: the pinhole view's pixels from the
floor to the ceiling of its sources' coordinates), a render size apart from the output size
(``sidar_torch.render.canvas``: the view's camera with its principal point moved by the canvas's
origin, the same focal length), each view its own box. The renderer then bends every per-view image
into the distorted view in GL (``sidar_torch.render.resample``: each pixel's source in float32, a
bilinear blend of the window's pixels with float weights, as ``grid_sample`` with border padding);
masks and the background flag are blended as fractions and cut at 1/2, so they stay binary, and only
the output's pixels are read back. The label is view 0's pinhole camera at the output size, as
without a lens. The view effects (``sidar_torch.sample.effects``) come after, as a sensor's do.
"""

from __future__ import annotations

import functools
from typing import Any, Mapping

import numpy as np
import torch
import torch.nn.functional as F

from ..choices.lenses import LENS_MODELS, NO_LENS, distorted_points, undistorted_grid, undistorted_points
from ..scene import SceneSequence
from ..timing import timed

__all__ = ["SOURCE_SLACK", "distortion_maps", "lens_canvas", "render_through_lens", "undistort"]


@functools.lru_cache(maxsize=4)
def _pixel_grid(image_size: tuple[int, int]) -> np.ndarray:
    """``(H, W, 2)`` float64 Kornia pixel coordinates ``(u, v)`` of every pixel (read-only, shared)."""
    h, w = image_size
    grid = np.empty((h, w, 2))
    grid[..., 0] = np.arange(w)
    grid[..., 1] = np.arange(h)[:, None]
    grid.flags.writeable = False
    return grid


def distortion_maps(model: str, lenses: np.ndarray | None, K: np.ndarray, image_size: tuple[int, int]) -> np.ndarray:
    """For each view and distorted pixel, where it comes from in the undistorted (pinhole) view.

    Args:
        model: ``lens_model`` (``"none"``: every pixel from itself).
        lenses: ``(V, 5)`` float64 coefficients (``sidar_torch.choices.lenses``), None for ``"none"``.
        K: ``(V, 3, 3)`` pinhole intrinsics, pixels.
        image_size: ``(H, W)``.

    Returns:
        ``(V, H, W, 2)`` float64 Kornia pixels ``(u, v)`` of the undistorted view: each pixel's own answer (an
        iterative model: safeguarded Newton's method from the GL pass's start, ended within its tolerance,
        ``choices.lenses.NEWTON_TOLERANCE``, at every pixel).

    Raises:
        ValueError: a lens whose iterative inverse does not converge at some pixel (one that folds the view,
            ``choices.lenses.lens_folds``), naming it and the worst residual.
    """
    grid = _pixel_grid(tuple(image_size))
    if model == NO_LENS:
        return np.broadcast_to(grid, (len(K), *grid.shape)).copy()
    if not LENS_MODELS[model].iterative:
        return np.stack([undistorted_grid(model, lens, k, image_size) for lens, k in zip(lenses, K)])
    return np.stack([undistorted_points(model, lens, k, grid) for lens, k in zip(lenses, K)])


SOURCE_SLACK = 1e-3
"""Pixels a source coordinate may pass a whole pixel before the canvas holds the next one: its bilinear
weight there is at most this (a quarter of a level at an edge of full contrast), and the resampling's
border clamp reads the window's last pixel instead. It covers the float32 rounding of the sources the
renderer resamples at (within about 2e-4 px of the exact maps: ``render.resample``), so a lens of zeros
draws the view itself."""


def lens_canvas(sources: np.ndarray) -> Any:
    """The canvas (``sidar_torch.render.Canvas``) that holds every pinhole pixel the bilinear resampling of
    each view reads with a weight above :data:`SOURCE_SLACK`: per view the box from the floor to the ceiling
    of its ``sources (V, ..., 2)`` (Kornia pixels of the undistorted view: ``LensResampling.border``, where the
    renderer's pass reads the view's border pixels, which a lens that does not fold makes the border of what
    it reads; or :func:`distortion_maps`), each view's origin its box's top-left pixel (rounded down to an
    even one: ``render.canvas.QUAD``) and its window the box from there (``Canvas.covering``)."""
    from ..render.canvas import Canvas  # as render_through_lens's import of render: at the first use

    flat = np.asarray(sources).reshape(len(sources), -1, 2)
    lo = np.floor(flat.min(axis=1) + SOURCE_SLACK).astype(np.int64)  # (V, 2) x, y
    hi = np.ceil(flat.max(axis=1) - SOURCE_SLACK).astype(np.int64)
    return Canvas.covering(np.concatenate([lo, np.maximum(hi, lo)], axis=1))


def render_through_lens(renderer: Any, sequence: SceneSequence, painting: np.ndarray,
                        texture: np.ndarray | None = None) -> Any:
    """Render ``sequence`` (with a lens) through its lenses: every per-view image distorted, the label not.

    Each view is drawn over its :func:`lens_canvas` window and bent into the distorted view by the
    renderer's resampling pass (``sidar_torch.render.resample``, in GL: each pixel's source in float32, a
    bilinear blend of the window's pixels, masks and background as fractions cut at 1/2).

    Args:
        renderer: a ``SceneRenderer`` of ``sequence.image_size`` (or a ``RenderProcess``).
        sequence: the scenes, ``sequence.lens_model`` not ``"none"``.
        painting, texture: ``(H, W, 3)`` uint8, as for ``SceneRenderer.render``.

    Timed steps (``sidar_torch.timing``): the renderer's (its ``"lens"``: the resampling pass) and ``"lens"``
    (the border's sources, the Newton steps of each view's program and the canvas).

    Returns:
        The distorted :class:`~sidar_torch.render.renderer.RenderedSequence` (the renderer's shapes and dtypes).

    Raises:
        ValueError: a canvas larger than the renderer's GL context allows (``SceneRenderer.render``).
    """
    from ..render.resample import LensResampling  # imports the GL libraries: at the first render, as the renderer's

    with timed("lens"):
        resampling = LensResampling.of(sequence)
        canvas = lens_canvas(resampling.border)
    return renderer.render(sequence, painting, texture=texture, canvas=canvas, lens=resampling)


def _bilinear(images: torch.Tensor, pixels: np.ndarray, padding: str) -> torch.Tensor:
    """``images (N, C, h, w)`` sampled bilinearly at ``pixels (N or 1, H, W, 2)`` or ``(H, W, 2)``
    (Kornia pixels of ``images``): ``(N, C, H, W)`` in ``images``' dtype; ``padding`` is ``grid_sample``'s."""
    h, w = images.shape[-2:]
    scale = torch.tensor([2 / max(w - 1, 1), 2 / max(h - 1, 1)], dtype=torch.float64)
    grid = torch.from_numpy(np.asarray(pixels, np.float64)) * scale - 1
    grid = grid.expand(len(images), *grid.shape[-3:]) if grid.ndim == 3 or len(grid) == 1 else grid
    return F.grid_sample(images, grid.to(images.dtype), mode="bilinear", padding_mode=padding, align_corners=True)


def undistort(sample: Mapping[str, Any], lens_model: str | None = None) -> dict[str, torch.Tensor]:
    """The undistorted (pinhole) views and masks of a sample rendered through a lens: what its
    ``homographies`` map between and ``K`` projects into.

    Each undistorted pixel is sampled bilinearly where the lens sends it
    (:func:`sidar_torch.choices.lenses.distorted_points`); pixels whose ray falls outside the distorted
    view are black and masked (1).

    Args:
        sample: a sample dict (or a batch: a leading ``B``) with ``images (V, 3, H, W)``, ``masks
            (V, 1, H, W)`` (float or uint8), ``K (V, 3, 3)``, ``lens (V, 5)`` and ``lens_model`` (the
            model's name; a batch: a list of ``B``), as :class:`sidar_torch.SidarDataset`,
            :class:`sidar_torch.SidarAugment` and :class:`sidar_torch.ExportedDataset` hand them out.
        lens_model: the model of ``lens`` (``"brown_conrady"`` or ``"division"``); None (the default):
            the sample's ``lens_model``. Needed only for a sample dict without ``lens_model``.

    Returns:
        A dict of the undistorted ``images`` and ``masks``, of the inputs' shapes and dtypes; masks
        stay in {0, 1} (``{0, 255}`` for uint8).

    Raises:
        ValueError: a sample without ``lens`` (rendered with ``lens_model: none``); ``lens_model`` not a
            lens model, or not the sample's (both named); neither ``lens_model`` nor the sample's.
    """
    if "lens" not in sample:
        raise ValueError("sample: expected a sample rendered through a lens (a 'lens' key; config lens_model "
                         "not 'none'), got one without")
    images, masks = sample["images"], sample["masks"]
    lead = images.shape[:-3]
    size = tuple(images.shape[-2:])
    K = sample["K"].reshape(-1, 3, 3).double().numpy()
    lenses = sample["lens"].reshape(-1, 5).double().numpy()
    models = _view_lens_models(sample, lens_model, len(lenses))
    grid = _pixel_grid(size)
    sources = np.stack([distorted_points(model, lens, k, grid) for model, lens, k in zip(models, lenses, K)])
    flat = images.reshape(-1, *images.shape[-3:])
    top = 255.0 if masks.dtype == torch.uint8 else 1.0
    seen = top - masks.reshape(-1, *masks.shape[-3:]).double()
    views = _bilinear(flat.double(), sources, "zeros")
    visible = _bilinear(seen, sources, "zeros")
    views = views.round() if images.dtype == torch.uint8 else views
    new_masks = torch.where(visible >= top / 2, 0.0, top)
    return {"images": views.to(images.dtype).reshape(*lead, *views.shape[-3:]),
            "masks": new_masks.to(masks.dtype).reshape(*lead, *new_masks.shape[-3:])}


def _view_lens_models(sample: Mapping[str, Any], lens_model: str | None, n_lenses: int) -> list[str]:
    """The lens model of each of the ``n_lenses`` lenses of ``sample`` (views, batch-major): the
    sample's ``lens_model`` (a batch's list: one per sample), checked against ``lens_model`` if given."""
    if lens_model is not None and lens_model not in LENS_MODELS:
        raise ValueError(f"lens_model: expected one of {sorted(LENS_MODELS)}, got {lens_model!r}")
    recorded = sample.get("lens_model")
    if recorded is None:
        if lens_model is None:
            raise ValueError("lens_model: the sample records no lens_model (a dict made without one); pass the "
                             f"lens_model that made it, one of {sorted(LENS_MODELS)}")
        return [lens_model] * n_lenses
    per_sample = [recorded] if isinstance(recorded, str) else list(recorded)
    for model in per_sample:
        if model not in LENS_MODELS:
            raise ValueError(f"sample['lens_model']: expected one of {sorted(LENS_MODELS)}, got {model!r}")
        if lens_model is not None and model != lens_model:
            raise ValueError(f"lens_model: {lens_model!r} contradicts the sample's lens_model {model!r}, the model "
                             f"its views were rendered with; leave lens_model out to use the sample's")
    if n_lenses % len(per_sample):
        raise ValueError(f"sample['lens_model']: expected one model per sample, got {len(per_sample)} for "
                         f"{n_lenses} views")
    return [model for model in per_sample for _ in range(n_lenses // len(per_sample))]
