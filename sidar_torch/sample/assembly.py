"""The one path that assembles a sample's arrays from the renderer's output (:func:`render_arrays`): the
render (through a lens when the scene has one), the homographies of every pair, the computed outputs
(:data:`COMPUTATIONS`) and the view effects, into a :class:`~.contract.SampleArrays`.

Shapes: ``V`` views of ``H x W`` pixels.
"""

from __future__ import annotations

from dataclasses import fields
from typing import TYPE_CHECKING, Any, Callable, Sequence

import numpy as np
import torch

from .. import geometry
from ..choices.lenses import NO_LENS
from ..choices.outputs import OUTPUTS
from ..config import SidarConfig
from ..render.settings import RenderSettings
from ..scene import SceneSequence
from ..timing import timed
from .contract import SampleArrays
from .depth_flow import depth_flow
from .effects import apply_effects, blur_painting, draw_effects
from .lens_views import distortion_maps, render_through_lens

if TYPE_CHECKING:  # the renderer's module imports pyrender; the caller made the renderer
    from ..render import SceneRenderer

__all__ = ["COMPUTATIONS", "batch_homographies", "render_arrays", "render_sample", "sequence_homographies"]


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
    return batch_homographies([sequence])[0]


def batch_homographies(sequences: Sequence[SceneSequence]) -> list[tuple[torch.Tensor, float]]:
    """:func:`sequence_homographies` of each of ``sequences`` (at least one, all with the same number
    of views), with one Kornia DLT call for all their pairs: the values each would get alone."""
    views = {len(sequence.views) for sequence in sequences}
    if len(views) != 1:
        raise ValueError(f"sequences: expected at least one, all with the same number of views, got "
                         f"{[len(sequence.views) for sequence in sequences]} views")
    sizes = {tuple(sequence.image_size) for sequence in sequences}
    if len(sizes) != 1:
        raise ValueError(f"sequences: expected one image_size, got {sorted(sizes)}")
    K, R, t = (np.stack(cameras) for cameras in zip(*(sequence.cameras() for sequence in sequences)))
    centres = [np.stack([view.camera.position for view in sequence.views]) for sequence in sequences]
    points = [geometry.project(*camera, geometry.fit_points(c)) for *camera, c in zip(K, R, t, centres)]
    fits = geometry.homographies_from_points(np.stack(points))
    pixels, inside = geometry.visible_plane_points(K, R, t, sizes.pop())
    truth = geometry.plane_induced_homographies(K, R, t)
    errors = geometry.point_disagreements(fits.numpy(), truth, pixels, geometry.shared_points(inside))
    return [(H, float(error)) for H, error in zip(fits, errors)]


def render_arrays(renderer: SceneRenderer, sequence: SceneSequence, painting: np.ndarray, config: SidarConfig,
                  index: int, *, rng: np.random.Generator | None = None,
                  homographies: tuple[torch.Tensor, float] | None = None) -> SampleArrays:
    """Render ``sequence`` with ``painting`` and assemble one sample's arrays: the one place a sample is made.

    Args:
        renderer: the :class:`~sidar_torch.render.SceneRenderer` to draw with, made for ``config``
            (``RenderSettings.from_config(config)``) by the caller that owns it: ``SidarDataset.renderer``,
            a render-pool worker (``sidar_torch.data.render_pool``), a test or a benchmark. Warming it up is
            the owner's business (``sidar_torch.sample.warm_up``); nothing here compiles ahead.
        sequence: the scenes (``sequence.image_size`` must be ``config.image_size``).
        painting: ``(H, W, 3)`` uint8 RGB, the texture, already fitted to ``config.image_size``.
        config: the renderer's settings (image size, shadow-map size and filter, the drawn outputs, ...),
            the views' texture (``texture_blur_sigma``), the computed outputs and the view effects
            (:mod:`sidar_torch.sample.effects`: background, exposure, noise, JPEG; off by default).
        index: stored as the sample's ``index``.
        rng: the generator that drew ``sequence``; the view effects draw from it next. Needed only
            when ``config`` switches an effect on (``ValueError`` otherwise).
        homographies: ``sequence_homographies(sequence)``, when computed already (with other
            sequences', :func:`batch_homographies`); default: computed here.

    Timed steps (``sidar_torch.timing``): the renderer's (:meth:`sidar_torch.render.SceneRenderer.render`),
    ``"upload"`` (the blurred texture), ``"lens"`` (:func:`~.lens_views.render_through_lens`), ``"effects"``
    (the view effects, when any is on), ``"homographies"`` and each computed output's producer (``"flow"``:
    ``flow_output``).

    Raises:
        ValueError: ``renderer``'s settings are not ``config``'s (naming the fields that differ).
    """
    _check_renderer(renderer, config)
    effects = draw_effects(config, len(sequence.views), sequence.image_size, rng)
    texture = None
    if config.texture_blur_sigma > 0:  # the views see the painting blurred, the label stays exact
        with timed("upload"):
            texture = blur_painting(painting, config.texture_blur_sigma)
    if sequence.lens_model == NO_LENS:
        rendered = renderer.render(sequence, painting, texture=texture)
    else:  # the lens's optics before the sensor's effects
        rendered = render_through_lens(renderer, sequence, painting, texture)
    views, outputs = rendered.views, dict(rendered.outputs)
    if effects is not None:
        with timed("effects"):
            views = apply_effects(views, rendered.background, effects)
            for name in [name for name in outputs if OUTPUTS[name].view_effects]:  # the same draws
                outputs[name] = apply_effects(outputs[name], rendered.background, effects)
    if homographies is None:
        with timed("homographies"):
            homographies = sequence_homographies(sequence)
    homographies, homography_error = homographies
    K, R, t = sequence.cameras()
    outputs = _with_computed_outputs(outputs, config, K, R, t)
    if config.distortion_map_output:
        with timed("lens"):
            maps = distortion_maps(sequence.lens_model, sequence.lenses, K, sequence.image_size)  # float64, exact
            outputs["distortion_maps"] = np.ascontiguousarray(maps.transpose(0, 3, 1, 2), np.float32)
    return SampleArrays(images=views, masks=rendered.masks.astype(np.uint8) * np.uint8(255), label=rendered.label,
                        homographies=homographies.numpy(), homography_error=homography_error, K=K, R=R, t=t,
                        index=index, lens=sequence.lenses,
                        lens_model=None if sequence.lenses is None else sequence.lens_model, **outputs)


def _check_renderer(renderer: SceneRenderer, config: SidarConfig) -> None:
    """Raise unless ``renderer`` was made for ``config``'s :class:`~sidar_torch.render.RenderSettings`."""
    expected = RenderSettings.from_config(config)
    if renderer.settings != expected:
        differ = [f.name for f in fields(expected) if getattr(renderer.settings, f.name) != getattr(expected, f.name)]
        raise ValueError(f"renderer: expected one made for config's settings (RenderSettings.from_config(config)), "
                         f"got one whose {', '.join(differ)} differ")


def _with_computed_outputs(outputs: dict[str, np.ndarray], config: SidarConfig, K: np.ndarray, R: np.ndarray,
                           t: np.ndarray) -> dict[str, np.ndarray]:
    """``outputs`` (the renderer's, by name) with the computed outputs the config asks for added
    (``OptionalOutput.computed_from``, each by its row of :data:`COMPUTATIONS`, timed under its producer's
    name) and the drawn ones only they needed left out."""
    asked = {name for name, row in OUTPUTS.items() if getattr(config, row.switch)}
    for name in sorted(asked):
        row = OUTPUTS[name]
        if row.computed_from is not None:
            with timed(row.producer):
                outputs[name] = COMPUTATIONS[row.producer](outputs[row.computed_from], K, R, t)
    return {name: array for name, array in outputs.items() if name in asked}


def _reference_flows(depth: np.ndarray, K: np.ndarray, R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """``(V, H, W, 2)`` float32: each view's flow to view 0 (:func:`sidar_torch.sample.depth_flow.depth_flow`), NaN where
    not valid, from ``depth`` ``(V, H, W)`` float32 and the cameras (float64)."""
    tensors = [torch.from_numpy(np.asarray(a, np.float64))[None] for a in (depth, K, R, t)]
    flows = []
    for i in range(len(depth)):
        flow, valid = depth_flow(*tensors, i, 0)
        flows.append(torch.where(valid, flow, torch.full_like(flow, float("nan")))[0])
    return torch.stack(flows).permute(0, 2, 3, 1).float().numpy()


COMPUTATIONS: dict[str, Callable[[np.ndarray, np.ndarray, np.ndarray, np.ndarray], np.ndarray]] = {
    "flow": _reference_flows,
}
"""The CPU steps that compute an output from a drawn one after read-back, by ``OptionalOutput.producer``
(``choices.outputs.OUTPUTS`` rows with ``computed_from``): each takes that output's ``(V, H, W[, C])`` array
and the cameras ``K``, ``R`` ``(V, 3, 3)``, ``t`` ``(V, 3)`` (float64) and returns the computed output's."""


def render_sample(renderer: SceneRenderer, sequence: SceneSequence, painting: np.ndarray, config: SidarConfig,
                  index: int, *, rng: np.random.Generator | None = None) -> dict[str, Any]:
    """:func:`render_arrays`, then :meth:`SampleArrays.to_tensors` in ``config.geometry_dtype``
    (timed as ``"tensors"``): the sample dict of :data:`KEYS`."""
    arrays = render_arrays(renderer, sequence, painting, config, index, rng=rng)
    with timed("tensors"):
        return arrays.to_tensors(config.geometry_dtype)
