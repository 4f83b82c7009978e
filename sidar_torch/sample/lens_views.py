"""Views through a lens: the CPU step after read-back that distorts every per-view image of a
sequence (:func:`render_through_lens`), the maps it resamples with (:func:`distortion_maps`) and the
way back for users (:func:`undistort`). The models and their conventions: :mod:`sidar_torch.choices.lenses`.

How a view is distorted, exactly. Each distorted pixel takes its colour from where the pinhole
camera sees the same ray, which may lie outside the pinhole view (barrel distortion sees more than
the view's pinhole field). The renderer draws every view at one size, so the wider undistorted
canvas is drawn in *tiles*: the view's camera with its principal point moved by whole image widths
or heights (``K[0, 2] -= ox``, ``K[1, 2] -= oy``: the same focal length, tile pixel ``(u, v)`` is
canvas pixel ``(u + ox, v + oy)``), as few as cover every source pixel (one, the view itself, when
the lens only pulls pixels inwards; 2 x 2 while the canvas is under twice the view's side, as for
every default range and the ``lens`` preset; up to 3 x 3 for the strongest barrel the bounds allow). The tiles are pasted
into the canvas and every image is resampled bilinearly into the distorted view (torch's
``grid_sample``); masks and the background flag are resampled as fractions and cut at 1/2, so they
stay binary. The view effects (``sidar_torch.sample.effects``) come after, as a sensor's do.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any, Mapping

import numpy as np
import torch
import torch.nn.functional as F

from ..choices.lenses import LENS_MODELS, NO_LENS, distorted_points, undistorted_points
from ..scene import Camera, SceneSequence
from ..timing import timed

__all__ = ["distortion_maps", "render_through_lens", "tile_origins", "undistort"]


def _pixel_grid(image_size: tuple[int, int]) -> np.ndarray:
    """``(H, W, 2)`` float64 Kornia pixel coordinates ``(u, v)`` of every pixel."""
    h, w = image_size
    v, u = np.mgrid[0:h, 0:w].astype(np.float64)
    return np.stack([u, v], -1)


def distortion_maps(model: str, lenses: np.ndarray | None, K: np.ndarray, image_size: tuple[int, int]) -> np.ndarray:
    """For each view and distorted pixel, where it comes from in the undistorted (pinhole) view.

    Args:
        model: ``lens_model`` (``"none"``: every pixel from itself).
        lenses: ``(V, 5)`` float64 coefficients (``sidar_torch.choices.lenses``), None for ``"none"``.
        K: ``(V, 3, 3)`` pinhole intrinsics, pixels.
        image_size: ``(H, W)``.

    Returns:
        ``(V, H, W, 2)`` float64 Kornia pixels ``(u, v)`` of the undistorted view.
    """
    grid = _pixel_grid(image_size)
    if model == NO_LENS:
        return np.broadcast_to(grid, (len(K), *grid.shape)).copy()
    return np.stack([undistorted_points(model, lens, k, grid) for lens, k in zip(lenses, K)])


def _axis_origins(lo: int, hi: int, n: int) -> list[int]:
    """Tile origins along an axis of ``n`` pixels whose tiles ``[o, o + n)`` cover ``[lo, hi]``:
    one tile, as close to the view (origin 0) as it can be, if one can; else tiles spread evenly."""
    count = math.ceil((hi - lo + 1) / n)
    if count == 1:
        return [int(np.clip(0, hi - n + 1, lo))]
    return sorted({int(round(o)) for o in np.linspace(lo, hi - n + 1, count)})


def tile_origins(sources: np.ndarray, image_size: tuple[int, int]) -> list[tuple[int, int]]:
    """The ``(ox, oy)`` origins of the tiles covering every pixel the bilinear resampling of one view's
    ``sources (H, W, 2)`` reads with a weight above 0 (``floor`` to ``ceil`` of each coordinate)."""
    h, w = image_size
    xs = _axis_origins(math.floor(sources[..., 0].min()), math.ceil(sources[..., 0].max()), w)
    ys = _axis_origins(math.floor(sources[..., 1].min()), math.ceil(sources[..., 1].max()), h)
    return [(ox, oy) for oy in ys for ox in xs]


def _tile(view: Any, ox: int, oy: int) -> Any:
    """``view`` (a ``ViewScene``) seen through its camera with the principal point moved by ``(-ox, -oy)``."""
    K = view.camera.K.copy()
    K[0, 2] -= ox
    K[1, 2] -= oy
    return dataclasses.replace(view, camera=Camera(K, view.camera.R, view.camera.t))


def render_through_lens(renderer: Any, sequence: SceneSequence, painting: np.ndarray,
                        texture: np.ndarray | None = None) -> tuple[Any, np.ndarray]:
    """Render ``sequence`` (with a lens) through its lenses: every per-view image distorted, the label not.

    Args:
        renderer: a ``SceneRenderer`` of ``sequence.image_size``.
        sequence: the scenes, ``sequence.lens_model`` not ``"none"``.
        painting, texture: ``(H, W, 3)`` uint8, as for ``SceneRenderer.render``.

    Timed steps (``sidar_torch.timing``): the renderer's and ``"lens"`` (maps, tiles, resampling).

    Returns:
        The distorted :class:`~sidar_torch.render.renderer.RenderedSequence` (the renderer's shapes and
        dtypes) and the :func:`distortion_maps` ``(V, H, W, 2)`` float64 it was resampled with.
    """
    from ..render import RenderedSequence  # imports the GL libraries: at the first render, as the renderer's

    size = tuple(sequence.image_size)
    with timed("lens"):
        K = sequence.cameras()[0]
        sources = distortion_maps(sequence.lens_model, sequence.lenses, K, size)
        origins = [tile_origins(s, size) for s in sources]
        # The renderer's label is drawn with its first view's camera: view 0's own comes first.
        first = [] if (0, 0) in origins[0] else [sequence.views[0]]
        origins[0].sort(key=lambda o: o != (0, 0))
        tiles = [_tile(view, ox, oy) for view, view_origins in zip(sequence.views, origins) for ox, oy in view_origins]
    rendered = renderer.render(SceneSequence(size, (*first, *tiles)), painting, texture=texture)
    with timed("lens"):
        names = sorted(rendered.outputs)
        planes = [rendered.views, rendered.masks[..., None], rendered.background[..., None],
                  *(rendered.outputs[name].reshape(*rendered.masks.shape, -1) for name in names)]
        stacked = np.concatenate(planes, -1)[len(first):]
        out, start = [], 0
        for view_sources, view_origins in zip(sources, origins):
            out.append(_resample(stacked[start:start + len(view_origins)], view_origins, view_sources, size))
            start += len(view_origins)
        out = np.stack(out)
        views = np.rint(out[..., :3]).clip(0, 255).astype(np.uint8)
        masks, background = out[..., 3] >= 0.5, out[..., 4] >= 0.5
        outputs, channel = {}, 5
        for name in names:
            c = 1 if rendered.outputs[name].ndim == 3 else 3
            block = np.rint(out[..., channel:channel + c]).clip(0, 255).astype(np.uint8)
            outputs[name] = block[..., 0] if c == 1 else block
            channel += c
    return RenderedSequence(views, masks, rendered.label, background, outputs), sources


def _resample(tiles: np.ndarray, origins: list[tuple[int, int]], sources: np.ndarray,
              image_size: tuple[int, int]) -> np.ndarray:
    """Paste one view's ``tiles (T, H, W, C)`` (any dtype) at ``origins`` into their canvas and sample it
    bilinearly at ``sources (H, W, 2)`` (view pixels): ``(H, W, C)`` float32."""
    h, w = image_size
    x0, y0 = min(o[0] for o in origins), min(o[1] for o in origins)
    width, height = max(o[0] for o in origins) + w - x0, max(o[1] for o in origins) + h - y0
    canvas = np.empty((height, width, tiles.shape[-1]), np.float32)
    # The view's own tile, if drawn, is pasted last: where tiles overlap, its pixels are the pinhole view's
    # (another tile's may differ at a few edge and shadow pixels: its shadow maps are fitted to what it sees).
    for tile, (ox, oy) in sorted(zip(tiles, origins), key=lambda pair: pair[1] == (0, 0)):
        canvas[oy - y0:oy - y0 + h, ox - x0:ox - x0 + w] = tile
    return _bilinear(torch.from_numpy(canvas).permute(2, 0, 1)[None], sources - (x0, y0), "border")[0].permute(1, 2, 0).numpy()


def _bilinear(images: torch.Tensor, pixels: np.ndarray, padding: str) -> torch.Tensor:
    """``images (N, C, h, w)`` sampled bilinearly at ``pixels (N or 1, H, W, 2)`` or ``(H, W, 2)``
    (Kornia pixels of ``images``): ``(N, C, H, W)`` in ``images``' dtype; ``padding`` is ``grid_sample``'s."""
    h, w = images.shape[-2:]
    grid = torch.from_numpy(pixels).to(torch.float64)
    grid = torch.stack([2 * grid[..., 0] / max(w - 1, 1) - 1, 2 * grid[..., 1] / max(h - 1, 1) - 1], -1)
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
