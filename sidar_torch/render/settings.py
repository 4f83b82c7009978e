"""Everything the renderer needs to know besides the scene: one small frozen value, no GL.

A :class:`RenderSettings` is built once from the configuration
(:meth:`RenderSettings.from_config`) or directly (tests, benchmarks), and is the only way
settings reach the renderer: ``SceneRenderer(settings)``, ``shared_renderer(settings)`` (which
keys this process's renderers on it) and ``renderer.render(sequence, painting)``. It reads the
configuration's fields by name, so the render layer never imports ``sidar_torch.config``.
"""

from __future__ import annotations

import math
import operator
from dataclasses import dataclass
from typing import Any

from ..choices.render import ANTIALIAS_SAMPLES, SHADOW_FILTERS, SHADOW_FRUSTA, TEXTURE_FILTERS, shadow_map_side
from ..choices.outputs import OUTPUTS, drawn_outputs

__all__ = ["RenderSettings"]


@dataclass(frozen=True)
class RenderSettings:
    """The renderer's settings (``SidarConfig`` documents the fields it sets).

    The defaults here are the plainest renderer (tent filter, fixed meshes), which hand-made test
    scenes rely on; ``SidarConfig``'s defaults are the settings the sweep chose (``docs/speed.md``).

    Attributes:
        image_size: ``(H, W)`` of every view, mask and label, in pixels.
        shadow_map_size: side of each shadow map, texels (a power of two >= 16).
        shadow_filter: ``"tent"`` (3 x 3 percentage-closer filter, 4 taps) or ``"bilinear"``
            (2 x 2, one tap).
        shadow_frustum: what each shadow map covers, ``"cone"`` or ``"fitted"``.
        mesh_error_px: ``None``: every curved occluder uses its fixed mesh (config
            ``mesh_detail: fixed``); a number: the coarsest pooled level whose silhouette (and
            shadow) stays within that many pixels of the true surface (``mesh_detail: auto``).
        texture_filter: the painting's filter, ``"trilinear"`` or ``"bilinear"``.
        shadows: whether lights cast shadows.
        occluders_visible: false: occluders cast shadows but cameras do not see them.
        mask_min_opacity: occluders whose ``material.base_color[3]`` is below this are left out
            of the masks (0: every occluder is masked).
        antialias: samples per pixel of each view's lit colour pass (1: none; 2, 4 or 8:
            multisampled, then resolved to one colour per pixel). Masks, opacities and the label are
            drawn single-sampled either way (config ``antialias``).
        outputs: the optional outputs to render too (names of the ``choices.outputs.OUTPUTS`` rows the
            renderer draws, those without ``computed_from``; ``RenderedSequence.outputs``); the other
            outputs are the same either way (the config fields of the rows' ``switch``).
        highlight_spill: over-exposed light spills into the other channels, a blown-out red turning
            white; false: each channel clips at white on its own (config ``highlight_spill``).
        light_radius: every emitter's radius, painting units: above 0, soft shadows (percentage-closer
            soft shadows, ``programs`` quirk 12) instead of ``shadow_filter`` (config ``light_radius``).
        group_emitters: the emitters of a light are shaded once, from their centre, and dimmed by the
            mean of their shadow lookups (``programs`` quirk 13; config ``area_light_shading``
            ``"per_light"``); false: each emitter is shaded on its own.
        mirrors: draw the painting reflected in reflective occluders and refracted through glass
            ones (``render.mirror``); off, they are drawn as before it existed (benchmarks
            compare). No config field sets it.
        skip_idle_shadows, cull_occluders, masks_from_outline, masks_from_stencil, reuse_shadow_maps,
            split_shadow_lookups, clear_written_texels, label_from_painting: the skips of work that
            cannot change a pixel (``render.plan``, ``render.footprints``, ``render.shadow_array`` and
            ``SceneRenderer``), all on; tests turn each off to compare. No config field sets them.
        footprint_tile: side of the square pixel tiles the painting's shadow lookups are resolved to
            (``render.footprints``): any side gives the same pixels; smaller tiles keep fewer
            lookups for more draws. No config field sets it.

    Raises:
        ValueError: a field out of its range, naming the field.
    """

    image_size: tuple[int, int]
    shadow_map_size: int = 1024
    shadow_filter: str = "tent"
    shadow_frustum: str = "fitted"
    mesh_error_px: float | None = None
    texture_filter: str = "trilinear"
    shadows: bool = True
    occluders_visible: bool = True
    mask_min_opacity: float = 0.0
    outputs: frozenset[str] = frozenset()
    antialias: int = 1
    highlight_spill: bool = True
    light_radius: float = 0.0
    group_emitters: bool = True
    mirrors: bool = True
    skip_idle_shadows: bool = True
    cull_occluders: bool = True
    masks_from_outline: bool = True
    masks_from_stencil: bool = True
    reuse_shadow_maps: bool = True
    split_shadow_lookups: bool = True
    clear_written_texels: bool = True
    label_from_painting: bool = True
    footprint_tile: int = 16

    def __post_init__(self) -> None:
        try:
            size = tuple(operator.index(n) for n in self.image_size)
        except TypeError:
            size = ()
        if len(size) != 2 or min(size) < 1:
            raise ValueError(f"image_size: expected (H, W), two integers >= 1, got {self.image_size!r}")
        object.__setattr__(self, "image_size", size)
        n = self.shadow_map_size
        if not isinstance(n, int) or isinstance(n, bool) or n < 16 or n & (n - 1):
            raise ValueError(f"shadow_map_size: expected a power of two >= 16, got {n!r}")
        for field, choices in (("shadow_filter", SHADOW_FILTERS), ("shadow_frustum", SHADOW_FRUSTA),
                               ("texture_filter", TEXTURE_FILTERS)):
            if getattr(self, field) not in choices:
                raise ValueError(f"{field}: expected one of {choices}, got {getattr(self, field)!r}")
        if self.mesh_error_px is not None and not self.mesh_error_px >= 0:
            raise ValueError(f"mesh_error_px: expected None or a number >= 0, got {self.mesh_error_px!r}")
        if self.antialias not in ANTIALIAS_SAMPLES or isinstance(self.antialias, bool):
            raise ValueError(f"antialias: expected one of {ANTIALIAS_SAMPLES} samples per pixel, got {self.antialias!r}")
        if not isinstance(self.footprint_tile, int) or isinstance(self.footprint_tile, bool) or self.footprint_tile < 1:
            raise ValueError(f"footprint_tile: expected an integer >= 1 (pixels), got {self.footprint_tile!r}")
        if not 0 <= self.light_radius < math.inf:
            raise ValueError(f"light_radius: expected a finite value >= 0, got {self.light_radius!r}")
        drawn = {name for name, row in OUTPUTS.items() if row.computed_from is None}
        if not isinstance(self.outputs, frozenset) or not self.outputs <= drawn:
            raise ValueError(f"outputs: expected a frozenset of {sorted(drawn)} (the outputs the renderer draws), "
                             f"got {self.outputs!r}")
        if not 0 <= self.mask_min_opacity <= 1:
            raise ValueError(f"mask_min_opacity: expected a value in [0, 1], got {self.mask_min_opacity!r}")

    @classmethod
    def from_config(cls, config: Any) -> RenderSettings:
        """The settings a ``SidarConfig`` (or any object with its field names) gives the renderer."""
        return cls(
            image_size=config.image_size, shadow_map_size=shadow_map_side(config.shadow_map_size, config.image_size),
            shadow_filter=config.shadow_filter, shadow_frustum=config.shadow_frustum,
            mesh_error_px=config.mesh_error_px if config.mesh_detail == "auto" else None,
            texture_filter=config.texture_filter, shadows=config.shadows,
            occluders_visible=config.occluders_visible, mask_min_opacity=config.mask_min_opacity,
            outputs=drawn_outputs({name for name, row in OUTPUTS.items() if getattr(config, row.switch)}),
            antialias=config.antialias,
            highlight_spill=config.highlight_spill, light_radius=config.light_radius,
            group_emitters=config.area_light_shading == "per_light",
        )

    def check_gl_limits(self, max_renderbuffer_size: int, max_texture_size: int) -> None:
        """Raise if a GL context with these limits cannot hold the renderer's buffers.

        Every view is drawn into renderbuffers of ``image_size`` and the painting is a texture of
        that size; each shadow map is a ``shadow_map_size`` square texture.

        Args:
            max_renderbuffer_size, max_texture_size: the context's ``GL_MAX_RENDERBUFFER_SIZE``
                and ``GL_MAX_TEXTURE_SIZE`` (pixels along a side).

        Raises:
            ValueError: naming the field, the context's limit, and what fits.
        """
        limit, name = min((max_renderbuffer_size, "GL_MAX_RENDERBUFFER_SIZE"),
                          (max_texture_size, "GL_MAX_TEXTURE_SIZE"))
        if max(self.image_size) > limit:
            raise ValueError(f"image_size: {self.image_size} (H, W) exceeds this OpenGL context's {name} = {limit}: "
                             f"expected H, W <= {limit}")
        if self.shadow_map_size > max_texture_size:
            fits = 1 << (max_texture_size.bit_length() - 1)
            raise ValueError(f"shadow_map_size: {self.shadow_map_size} exceeds this OpenGL context's "
                             f"GL_MAX_TEXTURE_SIZE = {max_texture_size}: expected a power of two <= {fits}")

    @property
    def shadow_taps(self) -> int:
        """The lookup's program define ``SIDAR_SHADOW_TAPS``: depth-compare taps per shadow lookup, 4
        (tent) or 1 (bilinear); 0 for soft shadows (``light_radius`` above 0)."""
        if self.light_radius > 0:
            return 0
        return 1 if self.shadow_filter == "bilinear" else 4
