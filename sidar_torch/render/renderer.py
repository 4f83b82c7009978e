"""The scene renderer: a :class:`~sidar_torch.scene.SceneSequence` and a painting in, pixels out.

:class:`SceneRenderer` owns one offscreen GL context and everything uploaded to it (shader
programs, meshes, shadow maps, the current painting's texture) and reuses them for every
sample. Create it in the process that uses it (a forked DataLoader worker takes over its parent's
shared renderers, or creates its own; see :func:`shared_renderer`).

Per view it draws, in the camera's pixel grid (Kornia convention, see ``geometry``):

* the **view**: the painting under the view's ambient level and lights, with occluders and
  shadows; 8-bit sRGB (the shader's output encoding is exact sRGB, see ``programs``);
  with ``settings.antialias`` > 1 drawn multisampled and resolved (``framebuffer``), the only
  pass that is;
* the **mask**: a segmentation draw of the painting (white) and the camera-visible occluders
  (black) with depth testing, so occluder parts behind the painting never count; background
  and occluders are 1. Occluders less opaque than ``settings.mask_min_opacity`` are left out
  of this draw, so the painting seen through them counts as visible. With no such occluder in
  view the mask is the painting's outline, computed without a draw
  (:func:`~.visibility.painting_mask`). When every camera-visible occluder is masked and the
  colour pass is single-sampled, that pass drew what this draw would, in the same order with the
  same depth test: it marks in the stencil the pixels whose depth the painting's fragments kept,
  and the mask is read from there, without its own draw (``tests/render/test_skips.py``);
* the **camera pass** (``Passes.camera_frame``, once per asked output it draws: ``depth``, ``normals``):
  the distance along the camera's axis, or the unit normal in the camera's frame, of the surfaces the
  mask draws (the painting and the occluders it counts), in float32;
* the **opacity** (only with ``opacities`` asked for): an unlit draw of the painting (white, opaque) and every
  camera-visible occluder (black, with the alpha and Fresnel rise of the colour draw), blended
  as the colour draw blends them, so each pixel keeps the fraction of the painting that shows
  through (see :func:`.unlit.render_opacity`).

and once per sequence the **label**: the painting through view 0's camera, unlit and without
occluders (the texture as the reference camera samples it).

A render may draw every view over a :class:`~.canvas.Canvas` instead of its own ``image_size`` pixels:
a window of its camera's pixel grid, larger (an overscan: the wider canvas a lens resamples) or
smaller (a crop); everything per view (culling, shadow frusta, footprints, masks, outputs) is then
of the canvas, the painting and the label keep ``image_size`` and view 0's own camera. With a lens
(``render.resample``), each view's window is then bent into its distorted view of ``image_size`` in GL,
right after its passes, and only those pixels are handed out.

Inside ``sidar_torch.timing.collect_timings()``, ``SceneRenderer.render`` adds the seconds spent in each step
to the collector (``upload``, ``graph``, ``shadow``, ``colour``, ``mask``, ``depth``, ``normals``, ``opacity``,
``shadow_mask``, ``label``, ``readback``; see ``render.passes`` for how GL time is attributed).

Lights are spot lights (``scene`` explains how point and area lights map to them). The
painting is left out of shadow maps: a plane lit from its front cannot shadow itself, and
occluder parts behind it are farther from the light than the plane, so they cannot darken it
either. This removes shadow acne on the painting altogether.

What each view draws (which occluders, which emitters get shadows) is planned in ``plan``;
work that cannot change a pixel is skipped there and here, each skip with its reason.

The pieces: ``settings`` (what to draw), ``plan`` and ``visibility`` (what each view needs),
``draws`` (a view's draw list) built by ``scene_graph`` from the scene description, ``meshes`` and
``gpu`` (what is uploaded), ``passes`` (the passes, with ``programs`` and ``shaders/``), ``resample`` (a lens's),
``shadow_maps``, ``transmittance``, ``unlit`` (label and opacity), ``context`` and ``framebuffer``
(the GL context and what it draws into). pyrender opens the context and does nothing else.
"""

from __future__ import annotations

import os
import weakref
from collections import Counter
from dataclasses import dataclass, field
from typing import Callable, Hashable

import numpy as np
from OpenGL import GL

from ..geometry import is_reference_camera
from ..choices.outputs import OUTPUTS
from ..scene import SceneSequence, ViewScene
from ..timing import timed
from .context import GL_PLATFORM, current_rasteriser, import_platform, open_context
from .draws import Surface, ViewDraws, world_pose
from .framebuffer import size_limits
from .gpu import PaintingTexture
from .meshes import MeshPool, mesh_level, plane_mesh
from .mirror import PaintingMirror
from .passes import LitPass, Passes, SegmentationPass, ShadowFractionPass
from .plan import ViewPlan, plan_views
from .canvas import Canvas
from .resample import LensResampling, Resampler
from .scene_graph import PAINTING_FILTERS, gl_material, view_draws
from .settings import RenderSettings
from .shadow_maps import ShadowMaps
from .unlit import render_label, render_opacity
from .visibility import painting_mask

__all__ = ["OUTPUT_PASSES", "DrawnView", "RenderedSequence", "SceneRenderer", "import_platform", "shared_renderer"]


@dataclass(frozen=True)
class RenderedSequence:
    """The pixels of one sequence.

    Attributes:
        views: ``(V, H, W, 3)`` uint8 sRGB.
        masks: ``(V, H, W)`` bool, True where the painting is not visible.
        label: ``(H, W, 3)`` uint8 sRGB, the painting as view 0's camera sees it, unlit.
        background: ``(V, H, W)`` bool, True where the view's colour draw drew nothing (neither
            the painting nor an occluder): the draw clears to alpha 0 and every surface writes a
            positive alpha, except transparent material without refraction of opacity under about
            0.06 over the background, whose blended alpha rounds to 0 in 8 bits (refracting glass
            writes alpha 1: it blends with the painting it shows itself, see ``render.mirror``).
        outputs: the optional outputs asked for (``RenderSettings.outputs``), by name: each row of
            ``choices.outputs.OUTPUTS`` drawn by its producer (:data:`OUTPUT_PASSES`), ``(V, H, W)`` or
            ``(V, H, W, C)`` of the row's dtype (uint8 levels, or float32 values), meaning what the row says.
    """

    views: np.ndarray
    masks: np.ndarray
    label: np.ndarray
    background: np.ndarray
    outputs: dict[str, np.ndarray] = field(default_factory=dict)


class SceneRenderer:
    """Renders scene sequences in one offscreen GL context, as ``settings`` say.

    Args:
        settings: image size, shadow maps, filters, mesh detail, outputs and skips
            (:class:`~.settings.RenderSettings`).

    Attributes:
        settings: as given.
        skipped: counts of skipped work since creation: ``"occluders_culled"`` (per view),
            ``"masks_from_outline"`` and ``"masks_from_stencil"`` (mask draws), ``"shadow_maps_reused"``
            (shadow passes), ``"label_from_painting"`` (label draws).

    Raises:
        ValueError: ``settings.image_size`` or ``shadow_map_size`` exceeds a limit of the GL context
            (:meth:`~.settings.RenderSettings.check_gl_limits`), or the context offers no
            ``settings.antialias`` samples per pixel (:class:`~.framebuffer.Framebuffer`).
    """

    def __init__(self, settings: RenderSettings):
        if not isinstance(settings, RenderSettings):
            raise TypeError(f"settings: expected a RenderSettings, got {type(settings).__name__}")
        self.settings = settings
        self.image_size = settings.image_size
        self.skipped: Counter[str] = Counter()
        h, w = self.image_size
        self._platform = open_context(w, h)
        # Destroying the context frees every GL object in it; it needs no current context, so a
        # collected renderer cannot disturb another one mid-render. Runs at exit too.
        self._release = weakref.finalize(self, self._platform.delete_context)
        self.gl_limits = size_limits()
        """``(GL_MAX_RENDERBUFFER_SIZE, GL_MAX_TEXTURE_SIZE)`` of this renderer's context."""
        settings.check_gl_limits(*self.gl_limits)  # before allocating: a clear error, not a GLError
        self._passes = Passes(w, h, settings.shadow_map_size, settings.shadow_taps, settings.antialias,
                              outputs=2 if _unblocked_asked(settings.outputs) else 1,
                              clear_written_texels=settings.clear_written_texels,
                              highlight_spill=settings.highlight_spill, light_radius=settings.light_radius)
        GL.glPixelStorei(GL.GL_UNPACK_ALIGNMENT, 1)
        self._meshes = MeshPool()
        self._plane = plane_mesh(self.image_size)
        self._shadows = ShadowMaps(self._passes, settings)
        self._textures: list[PaintingTexture | None] = [None, None]
        self._warmed_up: set[Hashable] = set()
        self._resampling: Resampler | None = None
        self.renders = 0
        """Sequences rendered so far, warm-ups included."""

    @property
    def program_count(self) -> int:
        """Number of shader programs built so far (constant once every variant has been used)."""
        return len(self._passes.programs)

    @property
    def program_variants(self) -> list[dict[str, int]]:
        """The defines of every shader program built so far, in the order they were built (``programs``)."""
        return self._passes.programs.variants

    @property
    def shadow_map_count(self) -> int:
        """Number of ``shadow_map_size``-square shadow maps (one per emitter rank): grows to the most
        emitters one view has used, then stays."""
        return self._shadows.layers

    def render(self, sequence: SceneSequence, painting: np.ndarray, *, texture: np.ndarray | None = None,
               canvas: Canvas | None = None, lens: LensResampling | None = None) -> RenderedSequence:
        """Render every view, mask and the label of ``sequence`` with ``painting`` as texture.

        Args:
            sequence: the scenes; its ``image_size`` must be this renderer's.
            painting: ``(H, W, 3)`` uint8 sRGB, the texture (one texel per reference-view pixel) and the label's.
            texture: ``(H, W, 3)`` uint8 sRGB, the texture the views (and the painting's reflections)
                see instead, e.g. the painting blurred (config ``texture_blur_sigma``); the label
                is drawn from ``painting`` either way. Default: ``painting``.
            canvas: the window of each view's pixel grid to draw (``render.canvas``): the
                :class:`RenderedSequence`'s per-view arrays are then of ``canvas.size``, each view's window
                in their first rows and columns (beyond it: zeros, masks and background true), its label
                of ``image_size`` (view 0's own camera). Default: each view itself.
            lens: with ``canvas``, each view's window bent through its lens into the view's ``image_size``
                pixels in GL (``render.resample``: bilinear, masks and background as fractions cut at 1/2):
                the per-view arrays are then of ``image_size``, the distorted views. Default: none.

        Raises:
            ValueError: ``sequence.image_size`` not this renderer's; ``painting`` or ``texture`` not
                ``(H, W, 3)`` uint8; ``canvas`` not one origin per view, or larger than this context's
                ``GL_MAX_RENDERBUFFER_SIZE`` (naming both); ``lens`` without a ``canvas``, or not one lens per view.

        Timed steps (``sidar_torch.timing``): ``"upload"`` (painting texture and meshes), ``"graph"``
        (building the draw lists), ``"shadow"``, ``"colour"``, ``"mask"``, ``"label"`` and each
        drawn output's (draw passes), ``"readback"`` and ``"lens"`` (the resampling pass, with its upload and
        read-back); the pixels are the same timed or not.
        """
        if tuple(sequence.image_size) != self.image_size:
            raise ValueError(f"sequence.image_size {sequence.image_size} != renderer image_size {self.image_size}")
        for name, array in (("painting", painting), ("texture", painting if texture is None else texture)):
            if array.shape != (*self.image_size, 3) or array.dtype != np.uint8:
                raise ValueError(f"{name}: expected {(*self.image_size, 3)} uint8, got {array.shape} {array.dtype}")
        if not self._release.alive:
            raise RuntimeError("SceneRenderer.render called after close()")
        framed, frames, size = self._framed(sequence, canvas)
        if lens is not None and (canvas is None or len(lens.lenses) != len(sequence.views)):
            raise ValueError(f"lens: expected a render.canvas.Canvas and one lens per view ({len(sequence.views)}), "
                             f"got canvas {type(canvas).__name__} and {len(lens.lenses)} lenses")
        self._platform.make_current()
        with timed("upload"):  # the texture object; its GL upload is timed in draw
            label_texture = self._painting_texture(painting, 0)
            texture = label_texture if texture is None else self._painting_texture(texture, 1)
        with timed("graph"):
            plans = plan_views(framed, self.settings, frames)
        views, masks, backgrounds, outputs = [], [], [], {name: [] for name in self.settings.outputs}
        for index, (view, plan, frame) in enumerate(zip(framed.views, plans, frames)):
            self._passes.resize(frame[1], frame[0])
            image, mask, extra = self._render_view(view, plan, framed, texture, frames, frame)
            if lens is None:
                image, mask = _padded(image, size, 0), _padded(mask, size, True)  # alpha 0 beyond: background
                extra = {name: _padded(array, size, 0) for name, array in extra.items()}
            else:
                with timed("lens", GL.glFinish):
                    image, mask, background, extra = self._resampler().resample(lens, index, canvas.origins[index],
                                                                                image, mask, extra)
                backgrounds.append(background)
            views.append(image)
            masks.append(mask)
            for name, array in extra.items():
                outputs[name].append(array)
        reference = sequence.views[0].camera
        if self.settings.label_from_painting and is_reference_camera(reference.K, reference.R, reference.t,
                                                                     self.image_size):
            # The reference camera sees texel (u, v) at pixel (u, v)'s centre: the label is the
            # painting, which the draw reproduces byte for byte (tests/render/test_skips.py).
            self.skipped["label_from_painting"] += 1
            with timed("label"):
                label = painting.copy()
        else:
            self._passes.resize(self.image_size[1], self.image_size[0])
            label = render_label(self._passes, reference, self._plane, label_texture, self.image_size)
        views = np.stack(views)
        if lens is None:
            views, background = np.ascontiguousarray(views[..., :3]), views[..., 3] == 0
        else:
            background = np.stack(backgrounds)
        self.renders += 1
        return RenderedSequence(views, np.stack(masks), label, background,
                                {name: np.stack(arrays) for name, arrays in outputs.items()})

    def lens_sources(self, lens: LensResampling) -> np.ndarray:
        """Where the lens's resampling pass reads each pixel of the distorted views of ``lens`` (a sequence's of
        this renderer's ``image_size``): ``(V, H, W, 2)`` float32 Kornia pixels ``(u, v)`` of the undistorted
        views, drawn by its shader (``render.resample``), before the clamp to each window."""
        self._platform.make_current()
        return np.stack([self._resampler().sources(lens, index) for index in range(len(lens.lenses))])

    def _resampler(self) -> Resampler:
        """The lens's resampling pass of this context (``render.resample``), made at the first lens."""
        if self._resampling is None:
            self._resampling = Resampler(self._passes.programs, self.image_size)
        return self._resampling

    def _framed(self, sequence: SceneSequence, canvas: Canvas | None
                ) -> tuple[SceneSequence, list[tuple[int, int]], tuple[int, int]]:
        """``sequence`` with its cameras drawing ``canvas`` (:meth:`Canvas.views`), the ``(H, W)`` window each
        view draws and the arrays' ``(H, W)``, checked against this context's renderbuffer limit;
        ``sequence`` itself and ``image_size`` without a canvas."""
        if canvas is None:
            return sequence, [self.image_size] * len(sequence.views), self.image_size
        if not isinstance(canvas, Canvas):
            raise TypeError(f"canvas: expected a render.Canvas or None, got {type(canvas).__name__}")
        limit = self.gl_limits[0]
        if max(canvas.size) > limit:
            raise ValueError(f"canvas size: {canvas.size} (H, W) exceeds this OpenGL context's "
                             f"GL_MAX_RENDERBUFFER_SIZE = {limit}: expected H, W <= {limit}")
        return canvas.views(sequence), [canvas.window(i) for i in range(len(sequence.views))], canvas.size

    def warm_up(self, sequence: SceneSequence, key: Hashable) -> bool:
        """Render ``sequence`` once, with a grey painting, and hand nothing out: the shader variants
        its draws meet are compiled now rather than in the middle of a later sample
        (``sidar_torch.sample.warm_up`` builds a sequence that meets every variant of a config).

        Nothing a later render reads is left changed: the GL objects it made (programs, meshes,
        shadow maps) are reused as any earlier sample's are, and the painting's texture and the
        shadow maps are keyed on their contents. :attr:`skipped` counts no warm-up work.

        Args:
            sequence: the scenes (``sequence.image_size`` must be this renderer's). With a lens, each view
                is also bent by the resampling pass (``render.resample``) at its lens, over a canvas of the
                view itself: for the identity lens (zero coefficients) that is all the pass reads, and it
                compiles the program most views of the default ranges take.
            key: names what ``sequence`` warms up; a renderer already warmed up with ``key``
                renders nothing.

        Returns:
            Whether it rendered (False: already warmed up with ``key``).
        """
        if key in self._warmed_up:
            return False
        skipped = self.skipped.copy()
        lens = canvas = None
        if sequence.lens_model != "none":  # the resampling pass's program too, drawn over the whole view
            lens = LensResampling.of(sequence)
            h, w = self.image_size
            canvas = Canvas.covering(np.tile([0, 0, w - 1, h - 1], (len(sequence.views), 1)))
        self.render(sequence, np.full((*self.image_size, 3), 128, np.uint8), canvas=canvas, lens=lens)
        self.skipped = skipped
        self._warmed_up.add(key)
        return True

    def rasteriser(self) -> dict[str, str]:
        """What draws this renderer's pixels: ``{"gl_renderer", "gl_version"}`` of its context
        (:func:`~.context.current_rasteriser`)."""
        self._platform.make_current()
        return current_rasteriser()

    def close(self) -> None:
        """Destroy the context and every GL object in it (safe to call twice)."""
        self._release()

    def disown(self) -> None:
        """Retire this renderer without touching its context: for a forked child holding a copy of
        its parent's renderer, whose GL state it must neither use nor free (see :func:`shared_renderer`).

        The renderer is kept alive for the rest of the process: the inherited context may still
        be current, and freeing its pixel buffer (or letting pyrender's ``Platform.__del__``
        destroy it) would hand Mesa freed or foreign state.
        """
        self._release.detach()
        _DISOWNED.append(self)

    def _painting_texture(self, painting: np.ndarray, slot: int) -> PaintingTexture:
        """The texture of ``painting`` in ``slot`` (0: the label's and, by default, the views'; 1: the
        views' own, ``render``'s ``texture``): made at the slot's first painting, refilled with each
        new one (``PaintingTexture.replace``: every painting is ``image_size``), uploaded at its first draw."""
        held = self._textures[slot]
        if held is None:
            self._textures[slot] = PaintingTexture(painting.copy(), PAINTING_FILTERS[self.settings.texture_filter])
        elif not np.array_equal(painting, held.rgb):
            held.replace(painting.copy())
        return self._textures[slot]

    def _render_view(self, view: ViewScene, plan: ViewPlan, sequence: SceneSequence, texture: PaintingTexture,
                     frames: list[tuple[int, int]], frame: tuple[int, int]
                     ) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
        """The view ``(H, W, 4)`` uint8 (RGB and the draw's alpha), its mask ``(H, W)`` bool and its
        optional outputs (``settings.outputs``, see :class:`RenderedSequence`), drawing what ``plan`` says
        over ``frame (H, W)`` pixels (its canvas window, or ``image_size``); ``frames``: every view's."""
        with timed("graph"):
            draws = view_draws(view.camera, view.ambient, self._plane, view.plane_material, texture, self.image_size,
                               frame)
            self._passes.painting = (PaintingMirror.of_view(texture, self.image_size, view.plane_material)
                                     if self.settings.mirrors else None)
            # Every occluder is listed, culled or not: they set the depth range of the cone-fitted
            # shadow cameras (``ViewDraws.scale``). A culled one is just never drawn.
            counts: dict[tuple[str, int], int] = {}
            for occ in view.occluders:
                key = (occ.shape, occ.variant, mesh_level(occ, view, self.settings))
                mesh = self._meshes.take(*key[:2], counts.setdefault(key, 0), key[2])
                counts[key] += 1
                draws.occluders.append(Surface(mesh, world_pose(occ.object_to_world()), gl_material(occ.material)))
            self.skipped["occluders_culled"] += len(draws.occluders) - len(plan.drawn | plan.casters)
            shadowed = self._shadows.add_lights(draws, view, plan.order, plan.n_shadowed)
            casters = [draws.occluders[i] for i in sorted(plan.casters)]
            transmitting = [draws.occluders[i] for i in sorted(plan.casters)
                            if view.occluders[i].material.transparent and not view.occluders[i].material.opaque_shadow]
            self._passes.shadow_frusta = self._shadows.frusta(shadowed, view, sequence, frames)
            map_keys = self._shadows.map_keys(draws, shadowed, [s for s in casters if not any(s is t for t in transmitting)])
            stale = self._shadows.stale(map_keys)
            self.skipped["shadow_maps_reused"] += len(shadowed) - len(stale)
        drawn = [draws.occluders[i] for i in sorted(plan.drawn)]
        # With no emitter that can cast a shadow on what the camera sees (the painting is not a
        # caster), the lit draw without lookups gives the same pixels without the shadow passes.
        # The unblocked colour comes from the same draw (a second output, quirk 10); without a
        # shadowed light the view is its own unblocked colour.
        outputs = self.settings.outputs
        both = _unblocked_asked(outputs) and bool(shadowed)
        # The colour pass leaves the mask's answer in the stencil whenever it can (single-sampled):
        # always, so that its programs meet the same GL state in every view (one llvmpipe variant each).
        stencil = self.settings.masks_from_stencil and self.settings.antialias == 1
        colour = LitPass(casters, transmitting, shadowed, plan.painting_parts, stale=stale, shadow_free=both,
                         stencil=stencil)
        with self._passes.target.multisampled():  # settings.antialias samples; the other passes single-sampled
            image = self._passes.draw(draws, colour, [draws.painting, *drawn])
        image, unblocked = (image[0], image[1, ..., :3]) if both else (image, image[..., :3])
        self._shadows.drawn(map_keys)
        masked = [draws.occluders[i] for i in sorted(plan.drawn)
                  if view.occluders[i].material.base_color[3] >= self.settings.mask_min_opacity]
        if not masked and self.settings.masks_from_outline:
            # Only the painting would be drawn: its pixels are those whose centre sees it, which is
            # what the rasteriser's rule computes, up to its sub-pixel vertex snapping.
            self.skipped["masks_from_outline"] += 1
            with timed("mask"):
                mask = painting_mask(view.camera.K, view.camera.R, view.camera.t, self.image_size, frame)
        elif stencil and len(masked) == len(drawn):
            # The mask's draw would draw what the colour pass drew, in the same order with the same
            # depth test: the painting is visible where its fragment kept the depth, which the colour
            # pass marked in the stencil.
            self.skipped["masks_from_stencil"] += 1
            with timed("mask"):
                mask = self._passes.target.read_stencil() != 1
        else:
            grey = {id(draws.painting): 255, **{id(s): 0 for s in masked}}
            seg = self._passes.draw(draws, SegmentationPass(grey), [draws.painting, *masked])
            mask = seg[..., 0] < 128
        drawn_view = DrawnView(draws, plan, drawn, masked, colour, mask, unblocked)
        extra = {name: OUTPUT_PASSES[row.producer](self, drawn_view)
                 for name, row in OUTPUTS.items() if name in outputs}
        return image, mask, extra

    def _render_shadow_mask(self, drawn: "DrawnView") -> np.ndarray:
        """``(H, W)`` uint8: 255 times the fraction of the direct light on the visible painting that
        occluders block, 0 where ``drawn.mask`` (painting not visible) is true.

        One draw of the painting alone with the lit program's ``SHADOW_FRACTION`` variant (quirk 9),
        the same shadow and transmittance maps as the colour pass (drawn by it just before: none is
        drawn again), in the footprint parts that have lookups only: elsewhere no light is blocked
        and the cleared framebuffer's 0 is the answer (``render.footprints``). A view without a
        shadowed light, or whose parts have no lookup, has no shadow, and no draw.
        """
        draws, plan = drawn.draws, drawn.plan
        parts = [part for part in plan.painting_parts if part.begin < part.end]
        colour = drawn.colour
        if not colour.shadowed or (plan.painting_parts and not parts):
            return np.zeros(drawn.mask.shape, np.uint8)
        fraction = ShadowFractionPass(colour.casters, colour.transmitting, colour.shadowed, parts)
        blocked = self._passes.draw(draws, fraction, [draws.painting])
        return np.where(drawn.mask, 0, blocked[..., 0]).astype(np.uint8)


@dataclass(frozen=True)
class DrawnView:
    """What a view's colour pass and mask left for the passes of its optional outputs.

    Attributes:
        draws: the view's draw list.
        plan: its plan (``render.plan``).
        drawn: the occluders the colour pass drew; masked: those of them the mask counts (at least
            ``mask_min_opacity`` opaque).
        colour: the colour pass (``passes.LitPass``): its shadow casters, transparent casters and
            shadowed emitters (whose maps hold this view's shadows).
        mask: ``(H, W)`` bool, True where the painting is not visible.
        unblocked: ``(H, W, 3)`` uint8 sRGB, the colour pass's view with no light blocked (its second
            output with a shadowed emitter; else the view itself).
    """

    draws: ViewDraws
    plan: ViewPlan
    drawn: list[Surface]
    masked: list[Surface]
    colour: LitPass
    mask: np.ndarray
    unblocked: np.ndarray


OutputPass = Callable[[SceneRenderer, DrawnView], np.ndarray]


def _camera_pass(quantity: str) -> OutputPass:
    """The producer of a quantity of the camera pass (``passes.CAMERA_QUANTITIES``), drawn from the
    surfaces the mask counts: the painting and the masked occluders."""
    return lambda renderer, drawn: renderer._passes.camera_frame(
        drawn.draws, [drawn.draws.painting, *drawn.masked], quantity)


OUTPUT_PASSES: dict[str, OutputPass] = {
    "unblocked_colour": lambda renderer, drawn: drawn.unblocked,
    "camera_depth": _camera_pass("depth"),
    "camera_normals": _camera_pass("normals"),
    "opacity": lambda renderer, drawn: render_opacity(renderer._passes, drawn.draws, drawn.drawn, drawn.mask),
    "shadow_fraction": lambda renderer, drawn: renderer._render_shadow_mask(drawn),
}
"""The renderer's producers of the drawn outputs, by ``OptionalOutput.producer`` (``choices.outputs.OUTPUTS``):
each returns one view's array of its output (:class:`RenderedSequence`) after the colour pass and the mask,
in the order of ``OUTPUTS``. ``unblocked_colour`` is no pass of its own: the colour pass draws it as a second
output whenever a row of this producer is asked for (:func:`_unblocked_asked`)."""


def _padded(array: np.ndarray, size: tuple[int, int], fill: float) -> np.ndarray:
    """``array (h, w, ...)`` in the first rows and columns of an ``(H, W, ...)`` array of ``size``, ``fill``
    elsewhere (``array`` itself when it is that size already)."""
    if array.shape[:2] == tuple(size):
        return array
    out = np.full((*size, *array.shape[2:]), fill, array.dtype)
    out[:array.shape[0], :array.shape[1]] = array
    return out


def _unblocked_asked(outputs: frozenset[str]) -> bool:
    """Whether ``outputs`` (names of ``choices.outputs.OUTPUTS``) holds one the colour pass draws as its
    second output (``unblocked_colour``)."""
    return any(OUTPUTS[name].producer == "unblocked_colour" for name in outputs)


_SHARED: dict[tuple, SceneRenderer] = {}
_DISOWNED: list[SceneRenderer] = []
"""Renderers inherited from a parent process, kept alive and unused (see ``SceneRenderer.disown``)."""


def _inherited_contexts_usable() -> bool:
    """Whether a forked child may go on using the GL contexts it inherited: on OSMesa with llvmpipe
    rasterising in the calling thread (``LP_NUM_THREADS=0``, see ``sidar_torch.render``), a context
    is plain process memory (no thread, no device file), which the fork copied whole, compiled
    shader variants included. Elsewhere (EGL, a GPU driver, llvmpipe threads) it is not."""
    return GL_PLATFORM == "osmesa" and os.environ.get("LP_NUM_THREADS") == "0"


def shared_renderer(settings: RenderSettings) -> SceneRenderer:
    """This process's renderer for ``settings``, created at first use and then reused.

    A forked child (a DataLoader worker, a render-pool process) inherits its parent's renderers. On
    OSMesa without llvmpipe threads it takes them over: each is its own copy of the parent's, GL
    state and compiled shader variants included, so the child compiles only variants its parent
    never drew (``sidar_torch.sample.warm_up`` compiles every one a config needs) and renders the same
    pixels (``tests/test_processes.py``). Elsewhere it disowns them without touching their GL state
    and creates its own.
    """
    pid = os.getpid()
    adopt = _inherited_contexts_usable()
    for key in [k for k in _SHARED if k[0] != pid]:
        renderer = _SHARED.pop(key)
        if adopt:
            _SHARED[(pid, key[1])] = renderer
        else:
            renderer.disown()
    key = (pid, settings)
    if key not in _SHARED:
        _SHARED[key] = SceneRenderer(settings)
    return _SHARED[key]
