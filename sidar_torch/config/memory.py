"""The memory one sample needs, estimated from its config (checked against ``MAX_SAMPLE_BYTES``).

The figures are peak resident memory a sample added to a process that had already rendered a
tiny one, measured with ``resource.getrusage`` on llvmpipe (Mesa 22.3, torch 2.13 CPU) and rounded
up:

* per view and pixel, 25.5 bytes measured (views, masks and opacities as uint8 arrays, then as
  float32 tensors; ``(H, W)`` from 960 x 1280 to 1920 x 2560, 2 to 8 views): :data:`VIEW_PIXEL_BYTES`;
* per pixel once, 74 bytes measured (the renderer's colour and depth buffers and readback, the
  painting's texture and mipmaps, the label): :data:`FRAME_PIXEL_BYTES`;
* per pixel and sample of a multisampled pass (``antialias`` > 1), 8 bytes (RGBA8 colour and
  24-bit depth, measured 31 bytes per pixel at 4 samples): :data:`MULTISAMPLE_PIXEL_BYTES`;
* the optional outputs (``choices.outputs.OUTPUTS``), counted rather than measured: per view and pixel,
  a uint8 array and a float32 tensor of each (``shadow_free`` 3 channels, ``shadow_masks`` 1; opacities are
  in the measured figure above), and per pixel and sample a render target of its own (``shadow_free``'s
  second RGBA8 colour buffer): each row's ``view_pixel_bytes`` and ``target_pixel_bytes``;
* per ordered pair of views, 28.9 KB measured (the homography fit and its 17 x 17 lattice check,
  64 to 256 views): :data:`VIEW_PAIR_BYTES`;
* per shadow-map texel and shadowed emitter, a float32 depth texel and a quarter of an RGBA16F
  transmittance texel: :data:`SHADOW_TEXEL_BYTES`.
"""

from __future__ import annotations

from typing import Any, Mapping

from ..choices.render import shadow_map_side
from ..choices.outputs import OUTPUTS
from .allowed import LIGHT_EMITTERS

__all__ = ["estimated_sample_bytes", "output_bytes", "shadowed_emitters"]

VIEW_PIXEL_BYTES = 32
FRAME_PIXEL_BYTES = 96
MULTISAMPLE_PIXEL_BYTES = 8
VIEW_PAIR_BYTES = 32 * 1024
SHADOW_TEXEL_BYTES = 6


def shadowed_emitters(config: Any) -> int:
    """The most spot-light emitters one view of ``config`` can have, each with a shadow map when
    ``shadows`` is on: ``n_lights`` high end times the most emitters a drawn kind of light has
    (``allowed.LIGHT_EMITTERS``: ``area_light_samples`` for area lights, else one)."""
    per_light = max((getattr(config, field) if field else 1) for kind, field in LIGHT_EMITTERS.items()
                    if kind in config.light_types)
    return config.n_lights[1] * per_light


def estimated_sample_bytes(config: Any) -> int:
    """Bytes one sample of ``config`` (a ``SidarConfig``) needs at its peak, an upper estimate.

    ``H * W * (V * 32 + 96 + 8 * antialias) + V**2 * 32768 + maps * shadow_map_size**2 * 6`` for
    ``V`` views of ``(H, W)`` pixels (the ``8 * antialias`` term only when ``antialias`` > 1) and
    ``maps`` shadow maps of side ``shadow_map_size`` (``auto`` resolved: ``choices.render.shadow_map_side``;
    at least the one map the renderer always holds), plus, for each optional output switched on (a row of
    ``choices.outputs.OUTPUTS``), ``H * W * V * view_pixel_bytes`` and ``H * W * target_pixel_bytes *
    (1 + antialias)`` (``(1)`` without antialiasing): with ``shadow_free_output`` ``H * W * V * 15`` and
    ``H * W * 4 * (1 + antialias)``, with ``shadow_mask_output`` ``H * W * V * 5``; the module docstring says
    how each figure was obtained.
    """
    h, w = config.image_size
    views = config.n_views
    multisample = MULTISAMPLE_PIXEL_BYTES * config.antialias if config.antialias > 1 else 0
    maps = max(1, shadowed_emitters(config) if config.shadows else 0)
    samples = 1 + (config.antialias if config.antialias > 1 else 0)  # the single- and multisampled buffers
    outputs = {row.switch: getattr(config, row.switch) for row in OUTPUTS.values()}
    targets = sum(row.target_pixel_bytes * samples for row in OUTPUTS.values() if outputs[row.switch])
    return (output_bytes(config.image_size, views, outputs) + h * w * (multisample + targets)
            + views * views * VIEW_PAIR_BYTES
            + maps * shadow_map_side(config.shadow_map_size, config.image_size)**2 * SHADOW_TEXEL_BYTES)


def output_bytes(image_size: tuple[int, int], n_views: int, outputs: Mapping[str, Any]) -> int:
    """The part of :func:`estimated_sample_bytes` that only the image size, the view count and the
    output switches set: ``H * W * (V * (32 + optional outputs) + 96)`` bytes (the views and masks as
    arrays and tensors, the frame's buffers and label). A lower bound of the estimate of any config
    with these fields, so a sample over :data:`~.allowed.MAX_SAMPLE_BYTES` by it is refused
    whatever the other fields hold; the export reader bounds a recorded export with it.

    Args:
        image_size: ``(H, W)`` pixels, integers.
        n_views: ``V``, an integer.
        outputs: the switches of ``choices.outputs.OUTPUTS`` (each row's ``switch``, e.g. ``opacity_output``),
            true or false; a missing one counts as false.
    """
    h, w = image_size
    per_view = VIEW_PIXEL_BYTES + sum(row.view_pixel_bytes for row in OUTPUTS.values() if outputs.get(row.switch))
    return h * w * (n_views * per_view + FRAME_PIXEL_BYTES)
