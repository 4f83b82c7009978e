"""Views through a lens: the CPU step after read-back that distorts every per-view image of a
sequence (:func:`render_through_lens`), the maps it resamples with (:func:`distortion_maps`) and the
way back for users (:func:`undistort`). The models and their conventions: :mod:`sidar_torch.choices.lenses`.

How a view is distorted, exactly. Each distorted pixel takes its colour from where the pinhole
camera sees the same ray, which may lie outside the pinhole view (barrel distortion sees more than
the view's pinhole field). So each view is drawn once over the wider undistorted *canvas* that holds
every pixel its bilinear resampling reads (:func:`lens_canvas`: the pinhole view's pixels from the
floor to the ceiling of its sources' coordinates), a render size apart from the output size
(``sidar_torch.render.canvas``: the view's camera with its principal point moved by the canvas's
origin, the same focal length), each view its own box (the arrays of a sample's views are those of
the largest). Every image is then resampled bilinearly into the distorted view (torch's
``grid_sample``); masks and the background flag are resampled as fractions and cut at 1/2, so they
stay binary. The label is view 0's pinhole camera at the output size, as without a lens. The view
effects (``sidar_torch.sample.effects``) come after, as a sensor's do.
"""

from __future__ import annotations

import functools
import math
from typing import Any, Mapping

import numpy as np
import torch
import torch.nn.functional as F

from ..choices.lenses import CHUNK, LENS_MODELS, NO_LENS, distorted_points, undistorted_grid, undistorted_points
from ..scene import SceneSequence
from ..timing import timed

__all__ = ["LATTICE_STEP", "RESAMPLING_STEPS", "SOURCE_SLACK", "distortion_maps", "lens_canvas", "render_through_lens",
           "resampling_sources", "undistort"]


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
        ``(V, H, W, 2)`` float64 Kornia pixels ``(u, v)`` of the undistorted view: each pixel's own answer
        (an iterative model starts from the answers of a lattice :data:`LATTICE_STEP` pixels apart,
        interpolated, and ends within its tolerance: ``choices.lenses.NEWTON_TOLERANCE``).
    """
    grid = _pixel_grid(tuple(image_size))
    if model == NO_LENS:
        return np.broadcast_to(grid, (len(K), *grid.shape)).copy()
    if not LENS_MODELS[model].iterative:
        return np.stack([undistorted_grid(model, lens, k, image_size) for lens, k in zip(lenses, K)])
    return np.stack([undistorted_points(model, lens, k, grid, _lattice_start(model, lens, k, image_size))
                     for lens, k in zip(lenses, K)])


LATTICE_STEP = 8
"""Pixels between the points of the lattice whose answers, interpolated bilinearly, start an iterative
lens model at every pixel (:func:`distortion_maps`): within about a thousandth of a pixel for the default
ranges, so Newton's method ends in 2 steps instead of 4-5."""


def _lattice_start(model: str, lens: np.ndarray, K: np.ndarray, image_size: tuple[int, int],
                   normalised: bool = False) -> Any:
    """The undistorted points of a lattice spanning the view, about :data:`LATTICE_STEP` apart, interpolated
    bilinearly at every pixel, float32: ``(H, W, 2)`` pixels, or with ``normalised`` the normalised
    coordinates' two ``(H, W)`` planes."""
    h, w = image_size
    ys = np.linspace(0, h - 1, max(2, math.ceil((h - 1) / LATTICE_STEP) + 1))
    xs = np.linspace(0, w - 1, max(2, math.ceil((w - 1) / LATTICE_STEP) + 1))
    lattice = undistorted_points(model, lens, K, np.stack(np.meshgrid(xs, ys), -1))  # (ny, nx, 2)
    if normalised:
        y = (lattice[..., 1] - K[1, 2]) / K[1, 1]
        lattice = np.stack([(lattice[..., 0] - K[0, 2] - K[0, 1] * y) / K[0, 0], y], -1)
    planes = torch.from_numpy(np.ascontiguousarray(lattice.transpose(2, 0, 1), np.float32))[None]
    full = F.interpolate(planes, size=(h, w), mode="bilinear", align_corners=True)[0]  # float32: only a start
    return (full[0].numpy(), full[1].numpy()) if normalised else full.permute(1, 2, 0).numpy()


def resampling_sources(model: str, lenses: np.ndarray, K: np.ndarray, image_size: tuple[int, int]) -> np.ndarray:
    """The :func:`distortion_maps` a lens view is resampled at, in float32 as ``grid_sample`` reads them:
    ``(V, H, W, 2)`` float32 Kornia pixels of the undistorted view.

    A closed-form model (``division``) in float32 from each row's and column's normalised coordinate
    (float32 rounding: about 3e-5 px at 500 px from the principal point); an iterative one
    (``brown_conrady``) as one float32 Newton step from the exact answers of a lattice
    :data:`LATTICE_STEP` pixels apart interpolated bilinearly (within 0.01-0.2 px before the step,
    within :data:`SOURCE_SLACK` after: ``tests/render/test_canvas.py``). A third of the work of the
    float64 maps' Newton step and check; the maps a sample hands out stay the exact float64 ones.

    Args: as :func:`distortion_maps` (``model`` a lens model, not ``"none"``).
    """
    h, w = image_size
    row = LENS_MODELS[model]
    out = np.empty((len(K), h, w, 2), np.float32)
    rows = max(1, 4 * CHUNK // w)  # Newton's float32 operations on arrays that stay in the core's cache
    for view, (lens, k) in enumerate(zip(lenses, K)):
        y = ((np.arange(h, dtype=np.float64) - k[1, 2]) / k[1, 1])[:, None]
        x = np.broadcast_to((np.arange(w, dtype=np.float64)[None, :] - k[0, 2] - k[0, 1] * y) / k[0, 0], (h, w))
        x32, y32, lens32 = x.astype(np.float32), y.astype(np.float32), np.asarray(lens, np.float32)
        if row.iterative:
            u0, v0 = _lattice_start(model, lens, k, image_size, normalised=True)
            y32 = np.ascontiguousarray(np.broadcast_to(y32, (h, w)))
            for top in range(0, h, rows):
                part = slice(top, top + rows)
                u, v = row.undistort((x32[part], y32[part]), lens32, (u0[part], v0[part]), RESAMPLING_STEPS)
                _to_pixels(k, u, v, out[view, part])
        else:
            u, v = row.undistort((x32, y32), lens32, None, None)
            _to_pixels(k, *np.broadcast_arrays(u, v), out[view])
    return out


RESAMPLING_STEPS = 1
"""Newton steps of :func:`resampling_sources` from the lattice's start: one takes its error of 0.01-0.2 px
to the float32 rounding's (the error after a step is about its square times the map's curvature)."""


def _to_pixels(K: np.ndarray, u: np.ndarray, v: np.ndarray, out: np.ndarray) -> None:
    """Write the normalised points ``(u, v)`` as pixels ``K (u, v, 1)`` into ``out (..., 2)`` (float32)."""
    k = K.astype(np.float32)
    out[..., 0] = k[0, 0] * u + k[0, 1] * v + k[0, 2]
    out[..., 1] = k[1, 1] * v + k[1, 2]


SOURCE_SLACK = 1e-3
"""Pixels a source coordinate may pass a whole pixel before the canvas holds the next one: its bilinear
weight there is at most this (a quarter of a level at an edge of full contrast), and ``grid_sample``'s
border padding reads the canvas's last pixel instead. It covers :func:`resampling_sources`' float32
rounding, so a lens of zeros draws the view itself."""


def lens_canvas(sources: np.ndarray) -> Any:
    """The canvas (``sidar_torch.render.Canvas``) that holds every pinhole pixel the bilinear
    resampling of each view reads with a weight above :data:`SOURCE_SLACK`: per view the box from the floor
    to the ceiling of its ``sources (V, H, W, 2)`` (:func:`resampling_sources`, or :func:`distortion_maps`),
    each view's origin its box's top-left pixel (rounded down to an even one: ``render.canvas.QUAD``) and its
    window the box from there (``Canvas.covering``)."""
    from ..render.canvas import Canvas  # as render_through_lens's import of render: at the first use

    planes = [(view[..., 0], view[..., 1]) for view in sources]  # per view and axis: numpy's (1, 2) reduction is slow
    lo = np.floor(np.array([[u.min(), v.min()] for u, v in planes]) + SOURCE_SLACK).astype(np.int64)  # (V, 2) x, y
    hi = np.ceil(np.array([[u.max(), v.max()] for u, v in planes]) - SOURCE_SLACK).astype(np.int64)
    return Canvas.covering(np.concatenate([lo, np.maximum(hi, lo)], axis=1))


def render_through_lens(renderer: Any, sequence: SceneSequence, painting: np.ndarray,
                        texture: np.ndarray | None = None) -> Any:
    """Render ``sequence`` (with a lens) through its lenses: every per-view image distorted, the label not.

    Args:
        renderer: a ``SceneRenderer`` of ``sequence.image_size``.
        sequence: the scenes, ``sequence.lens_model`` not ``"none"``.
        painting, texture: ``(H, W, 3)`` uint8, as for ``SceneRenderer.render``.

    Timed steps (``sidar_torch.timing``): the renderer's and ``"lens"`` (maps, canvas, resampling).

    Returns:
        The distorted :class:`~sidar_torch.render.renderer.RenderedSequence` (the renderer's shapes and
        dtypes), resampled at :func:`resampling_sources` (the :func:`distortion_maps` in float32).

    Raises:
        ValueError: a canvas larger than the renderer's GL context allows (``SceneRenderer.render``).
    """
    from ..render import RenderedSequence  # imports the GL libraries: at the first render, as the renderer's

    size = tuple(sequence.image_size)
    with timed("lens"):
        K = sequence.cameras()[0]
        sources = resampling_sources(sequence.lens_model, sequence.lenses, K, size)
        canvas = lens_canvas(sources)
    rendered = renderer.render(sequence, painting, texture=texture, canvas=canvas)
    with timed("lens"):
        names = sorted(rendered.outputs)
        out = [_resample(_channels(rendered, i, names, canvas.window(i)), view_sources, origin)
               for i, (view_sources, origin) in enumerate(zip(sources, canvas.origins))]
        views = _levels([view[:3] for view in out])
        masks = torch.stack([view[3] >= 0.5 for view in out]).numpy()
        background = torch.stack([view[4] >= 0.5 for view in out]).numpy()
        outputs, channel = {}, 5
        for name in names:
            c = 1 if rendered.outputs[name].ndim == 3 else 3
            block = _levels([view[channel:channel + c] for view in out])
            outputs[name] = block[..., 0] if c == 1 else block
            channel += c
    return RenderedSequence(views, masks, rendered.label, background, outputs)


def _levels(planes: list[torch.Tensor]) -> np.ndarray:
    """The views' resampled ``planes`` (each ``(C, H, W)`` float32 levels, rounded in place) as
    ``(V, H, W, C)`` uint8."""
    out = np.empty((len(planes), *planes[0].shape[1:], planes[0].shape[0]), np.uint8)
    for view, plane in zip(torch.from_numpy(out), planes):  # bilinear weights keep 0-255 levels in 0-255
        view.copy_(plane.round_().permute(1, 2, 0))
    return out


def _channels(rendered: Any, index: int, names: list[str], window: tuple[int, int]) -> torch.Tensor:
    """View ``index``'s per-view images of ``rendered`` (a ``RenderedSequence``) in its ``window (h, w)`` as
    one ``(C, h, w)`` float32 tensor: RGB, mask, background, then each of ``names``' outputs' channels."""
    h, w = window
    planes = [rendered.views[index], rendered.masks[index][..., None], rendered.background[index][..., None],
              *(rendered.outputs[name][index].reshape(*rendered.masks.shape[1:], -1) for name in names)]
    planes = [plane[:h, :w] for plane in planes]
    count = sum(plane.shape[-1] for plane in planes)
    channels = torch.empty((count, h, w), dtype=torch.float32)
    start = 0
    for plane in planes:
        channels[start:start + plane.shape[-1]] = torch.from_numpy(plane).permute(2, 0, 1)
        start += plane.shape[-1]
    return channels


def _resample(channels: torch.Tensor, pixels: np.ndarray, origin: np.ndarray) -> torch.Tensor:
    """One view's canvas ``channels (C, h, w)`` float32, whose pixel ``(0, 0)`` is the view's pixel
    ``origin (2,)``, sampled bilinearly at the view's ``pixels (H, W, 2)`` float32 (border padding):
    ``(C, H, W)`` float32, a mask's fractions kept. ``pixels`` is turned into ``grid_sample``'s grid in place."""
    h, w = channels.shape[-2:]
    scale = torch.tensor([2 / max(w - 1, 1), 2 / max(h - 1, 1)])
    grid = torch.from_numpy(pixels).mul_(scale).sub_(torch.from_numpy(origin).float() * scale + 1)
    return F.grid_sample(channels[None], grid[None], mode="bilinear", padding_mode="border", align_corners=True)[0]


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
