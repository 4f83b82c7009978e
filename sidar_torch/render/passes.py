"""The renderer's passes over a view's draw list (``render.draws``), each read top to bottom.

:class:`Passes` owns what a context's passes share (programs, the framebuffer, the shadow-map array,
the transmittance maps, the lights' uniform blocks, two sampler objects) and draws:

* :meth:`Passes.draw` with a :class:`LitPass`: the **shadow passes** (:meth:`Passes._shadow_maps`: each
  stale map of a shadowed emitter, then the transmittance tiles of transparent casters), then the
  **colour pass** (:meth:`Passes._surfaces`): the seen surfaces in draw order, each with the surface
  program of its variant (``programs``), the pass's lighting, its material and, for the painting,
  its screen parts with their shadow-lookup ranges (``render.footprints``); optionally the
  shadow-free colour as a second output and the painting's stencil for the mask;
* with a :class:`ShadowFractionPass`: the same programs' shadow-fraction variant, reading the maps the
  colour pass just drew;
* with a :class:`SegmentationPass`: the mask draw (a grey level per surface, depth-tested);
* with an :class:`UnlitPass`: the label and opacity draws (``unlit.frag``);

and :meth:`Passes.camera_frame`: a quantity of the camera's frame at each pixel (its distance along the
camera's axis, its surface normal), float32 (``camera_frame.*``, :data:`CAMERA_QUANTITIES`).

Every pass draws into :class:`~.framebuffer.Framebuffer` upside down (``FLIP_Y``) and reads back.
Nothing of pyrender runs here: pyrender opens the GL context (``render.context``) and nothing else.

Where GL time lands: every pass ends with ``glFlush``, and llvmpipe with ``LP_NUM_THREADS=0``
rasterises the queued draws in this thread before a flush returns, so a pass's time is its own.
When timing, each step also ends with ``glFinish`` (a no-op here, but it keeps asynchronous
drivers, e.g. a GPU under EGL, from billing the draws to ``readback``); it changes no pixel.
"""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np
from OpenGL import GL

from ..choices.render import MAX_SHADOWED_LIGHTS
from ..timing import timed
from .draws import SpotEmitter, Surface, ViewDraws
from .footprints import PaintingPart
from .framebuffer import FLIP_Y, FloatFramebuffer, Framebuffer
from .light_block import LightBlocks
from .mirror import MIRROR_DEFINES, REFRACTION, PaintingMirror
from .programs import Program, ProgramCache
from .shadow_array import ShadowMapArray, TexelBox
from .transmittance import TransmittanceMaps
from .visibility import map_texel_boxes

__all__ = ["CAMERA_QUANTITIES", "UNROLLED_LIGHT_GROUPS", "CameraQuantity", "ForwardPass", "LitPass", "Passes",
           "SegmentationPass", "ShadowFractionPass", "UnlitPass", "frustum_projection", "light_group_count",
           "light_matrices", "shadow_depth_range"]

UNROLLED_LIGHT_GROUPS = 4
"""The most light groups the painting's program without lookups adds written out rather than in a loop
(``#elif defined(LIGHT_GROUPS)`` in ``shaders/surface.frag``); a view with more gets the loop. A
:class:`Passes` takes it as ``unrolled_light_groups``."""



def frustum_projection(frustum: np.ndarray) -> np.ndarray:
    """OpenGL projection ``(4, 4)`` of a frustum from :func:`~.visibility.light_frustum`.

    The frustum is in the OpenCV frame (y down, z forward); the light's pose is the same frame
    turned to OpenGL's (``scene_graph.gl_pose``: y up, looking along -z), so its window's y bounds
    swap sign. This is ``glFrustum(x0 n, x1 n, -y1 n, -y0 n, n, f)``.
    """
    x0, x1, y0, y1, n, f = frustum
    return np.array([
        [2 / (x1 - x0), 0.0, (x1 + x0) / (x1 - x0), 0.0],
        [0.0, 2 / (y1 - y0), -(y1 + y0) / (y1 - y0), 0.0],
        [0.0, 0.0, -(f + n) / (f - n), -2 * f * n / (f - n)],
        [0.0, 0.0, -1.0, 0.0],
    ])


def shadow_depth_range(scale: float) -> tuple[float, float]:
    """Near and far planes of a default shadow camera in a view of ``scale`` (``ViewDraws.scale``):
    1 % and 10x of it, pyrender's (the near plane is closer than any caster)."""
    return 0.01 * scale, 10 * scale


def light_matrices(light: SpotEmitter, scale: float, frustum: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """The shadow map's view and projection ``(4, 4)`` of ``light`` (computed once, then kept on it).

    The default frustum is square, ``2 outer cone + pi / 16`` wide, with depths from 1 % to 10x the
    view's ``scale`` (``ViewDraws.scale``). A fitted ``frustum`` (``shadow_maps.ShadowMaps.frusta``)
    gives the window and far plane, but the default near plane, which is closer than any caster:
    the lit shader's depth bias is a constant in window depth over w, about ``b z (f - n) / (f n)``
    painting units along the ray, so a tight near (~50x farther) would shrink it ~50x and curved
    occluders would shadow themselves in stripes (acne). 24-bit depth still resolves about 1e-5
    painting units at the painting with this near. The shadow pass and the lit shader's lookup both
    take the matrices from here, so a map is always read with the projection it was drawn with.
    """
    if light.matrices is None:
        V = np.linalg.inv(light.pose)
        near, far = shadow_depth_range(scale)
        if frustum is None:
            t = np.tan(float(np.clip(2 * light.outer_cone + np.pi / 16.0, 0.0, np.pi)) / 2.0)
            P = np.zeros((4, 4))
            P[0][0] = 1.0 / t
            P[1][1] = 1.0 / t
            P[3][2] = -1.0
            P[2][2] = (far + near) / (near - far)
            P[2][3] = (2 * far * near) / (near - far)
        else:
            P = frustum_projection(np.array([*frustum[:4], min(near, frustum[4]), frustum[5]]))
        light.matrices = V, P
    return light.matrices


def light_group_count(lights: Sequence[SpotEmitter]) -> int:
    """How many light groups the shader adds for ``lights`` (in their order, each group's first light
    says how many lights it spans; ``programs`` quirk 13)."""
    count = k = 0
    while k < len(lights):
        count += 1
        k += lights[k].group_size
    return count


@dataclass(frozen=True)
class CameraQuantity:
    """What :meth:`Passes.camera_frame` draws: one row of :data:`CAMERA_QUANTITIES`.

    Attributes:
        define: the ``shaders/camera_frame.*`` variant that writes it.
        channels: values per pixel (1: an ``(H, W)`` array; 3: ``(H, W, 3)``).
        attributes: the mesh's vertex attributes it reads besides the position (their location defines).
        empty: the value where no surface is hit. The target clears to 0, which no drawn value is (every
            surface lies beyond the near plane; a normal is a unit vector).
    """

    define: str
    channels: int
    attributes: tuple[str, ...]
    empty: float


CAMERA_QUANTITIES = {
    "depth": CameraQuantity("CAMERA_DEPTH", 1, ("INST_M_LOC",), np.inf),
    "normals": CameraQuantity("CAMERA_NORMALS", 3, ("INST_M_LOC", "NORMAL_LOC"), 0.0),
}
"""The camera pass's quantities, by name: ``depth``, the distance along the camera's axis (painting units);
``normals``, the unit surface normal in the OpenCV camera frame (x right, y down, z forward), facing the
camera (back faces are culled)."""


def _among(part: Sequence, whole: Sequence) -> bool:
    """Whether every item of ``part`` is one of ``whole`` (the same object)."""
    return all(any(item is other for other in whole) for item in part)


@dataclass(frozen=True)
class _Shadowing:
    """What a lit pass's shadows come from (the fields :class:`LitPass` and :class:`ShadowFractionPass` share).

    Attributes:
        casters: surfaces that cast shadows: those in ``transmitting`` go into the transmittance
            maps (drawn and looked up only when there is one), the others into the depth maps.
        transmitting: blended casters whose shadows let light through, tinted (some of ``casters``).
        shadowed: the emitters that get a shadow map and lookup; the first of the view's lights.
            None shadowed: the draw has no lookup at all.
        painting_parts: the painting's screen parts (``render.footprints``): with a shadowed emitter,
            the painting is drawn once per part, each with only its lookups; with them the painting
            also gets the light-group variant (``LIGHT_GROUPS``). None: drawn whole.
    """

    casters: Sequence[Surface] = ()
    transmitting: Sequence[Surface] = ()
    shadowed: Sequence[SpotEmitter] = ()
    painting_parts: Sequence[PaintingPart] | None = None

    def __post_init__(self) -> None:
        if not _among(self.transmitting, self.casters):
            raise ValueError("transmitting: expected some of casters, got a surface that casts no shadow")

    def tinted(self) -> list[Surface]:
        """The casters whose shadows go to the transmittance maps (those of ``transmitting``)."""
        return [s for s in self.casters if any(s is t for t in self.transmitting)]


@dataclass(frozen=True)
class LitPass(_Shadowing):
    """The colour pass: the seen surfaces under the view's ambient level and lights (``surface.frag``),
    after the shadow passes of the shadowed emitters (see :class:`_Shadowing` for the shared fields).

    Attributes:
        stale: the emitters of ``shadowed`` whose maps are drawn (default: all); the others' maps
            must already hold what this view would draw into them.
        shadow_free: also output the colour with every light unblocked (quirk 10); the framebuffer
            must have two outputs.
        stencil: also leave in the stencil buffer, per pixel, 1 where the fragment that kept the
            pixel's depth is the painting's and 0 elsewhere (``Framebuffer.read_stencil``): a
            single-sampled pass only.
        step: the name the pass is timed under (``sidar_torch.timing``).

    Raises:
        ValueError: ``transmitting`` not among ``casters``, ``stale`` not among ``shadowed``,
            ``shadow_free`` without a shadowed emitter, ``stencil`` without ``painting_parts`` (the
            painting's draw marks the stencil).
    """

    stale: Sequence[SpotEmitter] | None = None
    shadow_free: bool = False
    stencil: bool = False
    step: str = "colour"

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.stale is not None and not _among(self.stale, self.shadowed):
            raise ValueError("stale: expected some of shadowed, got an emitter that gets no shadow map")
        if self.shadow_free and not self.shadowed:
            raise ValueError("shadow_free: needs a shadowed emitter (without one the view is its own "
                             "shadow-free colour)")
        if self.stencil and self.painting_parts is None:
            raise ValueError("stencil: needs painting_parts (the painting's draw marks the stencil)")


@dataclass(frozen=True)
class ShadowFractionPass(_Shadowing):
    """The shadow mask's pass: the lit programs' ``SHADOW_FRACTION`` variant (quirk 9), which outputs in
    every colour channel the fraction of the direct light the occluders block, reading the maps the
    colour pass of the same view just drew with the same casters and emitters (none is drawn again).

    Attributes:
        step: the name the pass is timed under (``sidar_torch.timing``).

    Raises:
        ValueError: ``transmitting`` not among ``casters``; no shadowed emitter (then no light is blocked:
            no draw is needed).
    """

    step: str = "shadow_mask"

    def __post_init__(self) -> None:
        super().__post_init__()
        if not self.shadowed:
            raise ValueError("shadowed: expected at least one emitter (without one no light is blocked)")


@dataclass(frozen=True)
class SegmentationPass:
    """The mask draw: each surface in one grey level, depth-tested, unlit, single-sampled.

    Attributes:
        grey: the level (0-255) of each seen surface, keyed by ``id(surface)``.
        step: the name the pass is timed under (``sidar_torch.timing``).
    """

    grey: Mapping[int, float]
    step: str = "mask"


@dataclass(frozen=True)
class UnlitPass:
    """The unlit draw (``unlit.frag``): each surface's base colour with the lit draw's Fresnel opacity
    (quirk 5), blended as the colour pass blends it; no light, no shadow (``render.unlit``).

    Attributes:
        step: the name the pass is timed under (``sidar_torch.timing``): ``"label"``, ``"opacity"``.
    """

    step: str


ForwardPass = LitPass | ShadowFractionPass | SegmentationPass | UnlitPass
"""The passes :meth:`Passes.draw` draws, each a frozen record that checks its own combination."""


class Passes:
    """The passes of one GL context (current whenever a method is called).

    Args:
        width, height: the framebuffer's first size, pixels (:meth:`resize` changes it).
        shadow_map_size: side of each shadow map, texels (a power of two).
        shadow_taps: depth-compare taps per lookup (``programs`` quirk 3).
        samples: samples per pixel of the colour pass (antialiasing); the other passes use 1.
        outputs: colour outputs the framebuffer holds (2 for the shadow-free view).
        clear_written_texels: clear only the texels of a shadow or transmittance map that its last
            draw may have written (``shadow_array``); false: every map whole.
        highlight_spill: over-exposed light spills into the other channels (a blown-out red turns
            white); false: each channel clips at white on its own.
        light_radius: every emitter's radius (painting units); above 0 the lookups are soft.

    Attributes:
        painting: what reflective and glass occluders show in the next lit draws (set per view).
        shadow_frusta: emitter -> fitted frustum for the next draws (``id`` keyed; set per view).
    """

    def __init__(self, width: int, height: int, shadow_map_size: int, shadow_taps: int, samples: int = 1,
                 outputs: int = 1, clear_written_texels: bool = True, highlight_spill: bool = True,
                 light_radius: float = 0.0):
        self.width, self.height = width, height
        self.programs = ProgramCache(shadow_taps)
        self.target = Framebuffer(width, height, samples, outputs)
        self.shadow_map_size = shadow_map_size
        self.shadow_maps = ShadowMapArray(shadow_map_size)
        self.transmittance = TransmittanceMaps(shadow_map_size // 2)
        self.clear_written_texels = clear_written_texels
        self.highlight_spill = highlight_spill
        self.light_radius = light_radius
        self.unrolled_light_groups = UNROLLED_LIGHT_GROUPS  # 0: the painting's program keeps the loop
        self.painting: PaintingMirror | None = None
        self.shadow_frusta: dict[int, np.ndarray] = {}
        self._shadow_framebuffer = int(GL.glGenFramebuffers(1))
        self._light_blocks = LightBlocks()
        self._depth_sampler = self._sampler(GL.GL_NEAREST, GL.GL_NEAREST, compare=False)  # soft lookups' search
        self._mirror_sampler = self._sampler(GL.GL_LINEAR_MIPMAP_LINEAR, GL.GL_LINEAR)  # trilinear, any painting filter
        self._textures = 0  # texture units taken by the current surface's draw
        self._float_targets: dict[int, FloatFramebuffer] = {}  # by channels, made at the first camera pass

    @staticmethod
    def _sampler(minify: int, magnify: int, compare: bool = True) -> int:
        sampler = GL.glGenSamplers(1)
        parameters = [(GL.GL_TEXTURE_MIN_FILTER, minify), (GL.GL_TEXTURE_MAG_FILTER, magnify),
                      (GL.GL_TEXTURE_WRAP_S, GL.GL_CLAMP_TO_EDGE), (GL.GL_TEXTURE_WRAP_T, GL.GL_CLAMP_TO_EDGE)]
        if not compare:
            parameters.append((GL.GL_TEXTURE_COMPARE_MODE, GL.GL_NONE))
        for name, value in parameters:
            GL.glSamplerParameteri(sampler, name, value)
        return sampler

    def resize(self, width: int, height: int) -> None:
        """Draw and read ``width`` x ``height`` pixels in the next forward passes (a render's canvas,
        ``render.canvas``; the label's ``image_size``): the framebuffers grow if they must."""
        self.width, self.height = width, height
        self.target.resize(width, height)

    def matrices(self, view: ViewDraws, light: SpotEmitter) -> tuple[np.ndarray, np.ndarray]:
        """``light``'s shadow-map view and projection in ``view`` (:func:`light_matrices`)."""
        return light_matrices(light, view.scale, self.shadow_frusta.get(id(light)))

    # -- the draw --------------------------------------------------------------------------------

    def draw(self, view: ViewDraws, pass_: ForwardPass, seen: Sequence[Surface]) -> np.ndarray:
        """Draw ``view``'s ``seen`` surfaces in one forward pass and read the result back: ``(H, W, 4)``
        uint8 (with a :class:`LitPass`'s ``shadow_free``, ``(2, H, W, 4)``: the colour, then the colour
        with no light blocked).

        A :class:`LitPass` with shadowed emitters first draws their stale shadow maps (and, with
        transparent casters, the transmittance tiles). Timed (``sidar_torch.timing``) as ``"upload"``,
        ``"shadow"``, the pass's ``step`` and ``"readback"``.

        Raises:
            ValueError: a :class:`LitPass` with ``stencil`` on a multisampled framebuffer (antialias).
        """
        stencil = isinstance(pass_, LitPass) and pass_.stencil
        if stencil and self.target.samples > 1:
            raise ValueError("stencil: needs a single-sampled colour pass; this renderer draws it with "
                             f"{self.target.samples} samples per pixel (antialias)")
        shadowing = pass_ if isinstance(pass_, (LitPass, ShadowFractionPass)) else None
        with timed("upload", GL.glFinish):
            for surface in [*seen, *(shadowing.casters if shadowing is not None else ())]:
                surface.mesh.upload()
                if surface.material.texture is not None:
                    surface.material.texture.upload()
        lit = None
        if shadowing is not None:
            shadows = bool(shadowing.shadowed)
            tinted = shadowing.tinted() if shadows else []
            if shadows and isinstance(pass_, LitPass):  # a shadow fraction reads the maps its colour pass drew
                with timed("shadow", GL.glFinish):
                    self._shadow_maps(view, [s for s in pass_.casters if not any(s is t for t in tinted)], tinted,
                                      pass_.shadowed, pass_.shadowed if pass_.stale is None else pass_.stale)
            parts = shadowing.painting_parts
            shadow_free = isinstance(pass_, LitPass) and pass_.shadow_free
            lit = _LitDraw(shadows, bool(tinted), len(shadowing.shadowed), isinstance(pass_, ShadowFractionPass),
                           shadow_free, parts if parts is not None and shadows else None, self._light_groups(view, parts))
        with timed(pass_.step, GL.glFinish):
            self._surfaces(view, pass_, view.ordered(list(seen)), lit, stencil)
        with timed("readback"):
            images = self.target.end_drawing()
        return images if lit is not None and lit.shadow_free else images[0]

    def _light_groups(self, view: ViewDraws, painting_parts: Sequence[PaintingPart] | None) -> int | None:
        """The painting's written-out light groups (``LIGHT_GROUPS``), or None (the loop)."""
        if painting_parts is None:
            return None
        groups = light_group_count(view.lights)
        return groups if groups <= self.unrolled_light_groups else None

    def camera_frame(self, view: ViewDraws, surfaces: Sequence[Surface], quantity: str) -> np.ndarray:
        """A quantity of the camera's frame at each pixel centre, from the nearest of ``surfaces``: a row of
        :data:`CAMERA_QUANTITIES` (depth: ``(H, W)`` float32; normals: ``(H, W, 3)`` float32),
        its ``empty`` value where none is hit.

        One draw of each surface (back faces culled, depth-tested, no blending, nothing of its
        material) into a float target (:class:`~.framebuffer.FloatFramebuffer`), single-sampled
        whatever ``antialias`` is, with ``shaders/camera_frame.*`` under the quantity's define: the vertex
        stage's values interpolated perspective-correctly (the depth exact for a plane up to float32
        rounding, not the 24-bit depth buffer, whose resolution at the painting is about 1e-5 of the
        distance). Timed under the quantity's name (``"upload"``, ``"readback"``).
        """
        row = CAMERA_QUANTITIES[quantity]
        with timed("upload", GL.glFinish):
            for surface in surfaces:
                surface.mesh.upload()
        if row.channels not in self._float_targets:
            self._float_targets[row.channels] = FloatFramebuffer(self.width, self.height, row.channels)
        target = self._float_targets[row.channels]
        target.resize(self.width, self.height)
        camera = _Camera(np.linalg.inv(view.camera_pose), FLIP_Y @ view.projection, view.camera_pose[:3, 3])
        with timed(quantity, GL.glFinish):
            GL.glViewport(0, 0, self.width, self.height)
            GL.glEnable(GL.GL_DEPTH_TEST)
            GL.glDepthMask(GL.GL_TRUE)
            GL.glDepthFunc(GL.GL_LESS)
            GL.glDepthRange(0.0, 1.0)
            target.begin_drawing()
            GL.glClearColor(0.0, 0.0, 0.0, 0.0)  # 0: nothing drawn (no drawn value is: see CameraQuantity)
            target.clear(GL.GL_COLOR_BUFFER_BIT | GL.GL_DEPTH_BUFFER_BIT)
            GL.glDisable(GL.GL_MULTISAMPLE)
            for surface in surfaces:
                defines = {name: surface.mesh.defines[name] for name in row.attributes}
                program = self._program(("camera_frame.vert", "camera_frame.frag"), {**defines, row.define: 1})
                program.use()
                camera.set(program)
                self._draw_plain(surface, program)
            GL.glUseProgram(0)
            GL.glFlush()
        with timed("readback"):
            values = target.end_drawing()
        drawn = values.any(-1) if values.ndim == 3 else values != 0
        values[~drawn] = row.empty
        return values

    # -- shadow passes ---------------------------------------------------------------------------

    def _shadow_maps(self, view: ViewDraws, opaque: list[Surface], tinted: list[Surface],
                     shadowed: Sequence[SpotEmitter], stale: Sequence[SpotEmitter]) -> None:
        """Draw the depth map of every ``stale`` emitter (opaque casters) and, with ``tinted``
        casters, every shadowed emitter's transmittance tile (``render.transmittance``)."""
        corners = self._caster_corners(opaque)
        if stale:
            self._begin_depth_passes()
            matrices = [self.matrices(view, light) for light in stale]
            boxes = self._caster_texels(corners, [P @ V for V, P in matrices], self.shadow_map_size)
            for light, (V, P), writes in zip(stale, matrices, boxes):
                self._depth_pass(light.layer, V, P, opaque, writes)
            GL.glUseProgram(0)
        if tinted:
            # Tile k is read by the shader's k-th spot light.
            tiles = [(k, light) for k, light in enumerate(view.lights) if any(light is s for s in shadowed)]
            # A power of two of tiles: the texture's height stays a power of two as it grows, which
            # llvmpipe's fragment-shader variants depend on (a height of another kind would compile a
            # new variant of every transmittance program mid-stream; tiles are read by texelFetch at
            # their own place, so the room beyond changes no pixel).
            self.transmittance.reserve(1 << tiles[-1][0].bit_length())
            matrices = [self.matrices(view, light) for _, light in tiles]
            boxes = self._caster_texels(self._caster_corners(tinted), [P @ V for V, P in matrices],
                                        self.transmittance.tile)
            for (k, light), (V, P), writes in zip(tiles, matrices, boxes):
                self.transmittance.draw_tile(k, V, P, light.pose[:3, 3], tinted, self._transmittance_program, writes)

    def _begin_depth_passes(self) -> None:
        """The state every depth pass of a view draws with (:meth:`_depth_pass`), set once for all of them:
        the shadow framebuffer without colour buffers, the map's viewport, depth test and writes (on
        before the clears: the mask applies to them), back faces culled, no blending."""
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, self._shadow_framebuffer)
        GL.glDrawBuffer(GL.GL_NONE)
        GL.glReadBuffer(GL.GL_NONE)
        GL.glDepthMask(GL.GL_TRUE)
        GL.glViewport(0, 0, self.shadow_map_size, self.shadow_map_size)
        GL.glEnable(GL.GL_DEPTH_TEST)
        GL.glDepthFunc(GL.GL_LESS)
        GL.glDepthRange(0.0, 1.0)
        GL.glEnable(GL.GL_CULL_FACE)
        GL.glCullFace(GL.GL_BACK)
        GL.glDisable(GL.GL_BLEND)
        GL.glPolygonMode(GL.GL_FRONT_AND_BACK, GL.GL_FILL)

    def _depth_pass(self, layer: int, V: np.ndarray, P: np.ndarray, casters: list[Surface], writes: TexelBox) -> None:
        """Clear shadow map ``layer`` where its last draw wrote and draw ``casters``' depths from the
        light (``V``, ``P``), for a draw that writes only ``writes``, in the state of
        :meth:`_begin_depth_passes`. Each program (one per vertex layout) gets the light's matrices
        once, at its first caster; a program keeps its uniforms, so later casters set only their pose."""
        self.shadow_maps.attach(layer, writes)  # its scissored clear leaves the scissor test off
        lit: set[int] = set()  # ids of the programs holding this light's V and P
        for surface in casters:  # each texel keeps the nearest depth: the order changes none
            program = self._program(("depth.vert", "depth.frag"), {"INST_M_LOC": surface.mesh.defines["INST_M_LOC"]})
            program.use()
            if id(program) not in lit:
                lit.add(id(program))
                program.set_uniform("V", V)
                program.set_uniform("P", P)
            program.set_uniform("M", surface.pose)
            surface.mesh.draw()
        GL.glFlush()

    def _caster_corners(self, casters: list[Surface]) -> np.ndarray | None:
        """``(8 N, 3)`` world corners of the boxes of ``casters``, the same for every light of a view;
        ``None`` (every texel may be written) without ``clear_written_texels``."""
        if not self.clear_written_texels:
            return None
        corners = [surface.corners for surface in casters]
        return np.concatenate(corners) if corners else np.zeros((0, 3))

    @staticmethod
    def _caster_texels(corners: np.ndarray | None, light_matrices: list[np.ndarray], size: int) -> list[TexelBox]:
        """For each of ``light_matrices`` (``P V``, a light's), the texels of a ``size``-texel map that drawing
        casters with the box ``corners`` may write (``None``: the whole map), all at once (:func:`map_texel_boxes`)."""
        if corners is None:
            return [(0, 0, size, size)] * len(light_matrices)
        return map_texel_boxes(corners, light_matrices, size)

    def _transmittance_program(self, surface: Surface) -> Program:
        return self._program(("surface.vert", "transmittance.frag"), surface.mesh.defines)

    def _program(self, shaders: tuple[str, str], defines: dict[str, int]) -> Program:
        program = self.programs.get(shaders, defines)
        program.link()
        return program

    # -- forward passes --------------------------------------------------------------------------

    def _surfaces(self, view: ViewDraws, pass_: ForwardPass, ordered: list[Surface], lit: "_LitDraw | None",
                  stencil: bool) -> None:
        """One forward pass: clear, then draw ``ordered`` (see :meth:`draw`); ``lit``: what a lit pass's
        programs need, None for the others."""
        GL.glViewport(0, 0, self.width, self.height)
        GL.glEnable(GL.GL_DEPTH_TEST)
        GL.glDepthMask(GL.GL_TRUE)
        GL.glDepthFunc(GL.GL_LESS)
        GL.glDepthRange(0.0, 1.0)
        self.target.begin_drawing(2 if lit is not None and lit.shadow_free else 1)
        if stencil:  # cleared to 0; each fragment that passes the depth test writes its draw's value
            GL.glStencilMask(0xFF)
            GL.glClearStencil(0)
            self.target.clear(GL.GL_STENCIL_BUFFER_BIT)
            GL.glEnable(GL.GL_STENCIL_TEST)
            GL.glStencilOp(GL.GL_KEEP, GL.GL_KEEP, GL.GL_REPLACE)
        segmentation = pass_.grey if isinstance(pass_, SegmentationPass) else None
        # Alpha 0: background (the segmentation draw clears to opaque black).
        GL.glClearColor(*((0.0, 0.0, 0.0, 1.0) if segmentation is not None else (0.0, 0.0, 0.0, 0.0)))
        self.target.clear(GL.GL_COLOR_BUFFER_BIT | GL.GL_DEPTH_BUFFER_BIT)
        (GL.glDisable if segmentation is not None else GL.glEnable)(GL.GL_MULTISAMPLE)
        camera = _Camera(np.linalg.inv(view.camera_pose), FLIP_Y @ view.projection, view.camera_pose[:3, 3])
        lighting = _PassLighting(self, view, lit) if lit is not None else None
        try:
            for surface in ordered:
                if stencil:
                    GL.glStencilFunc(GL.GL_ALWAYS, int(surface is view.painting), 0xFF)
                if segmentation is not None:
                    program = self._program(("depth.vert", "segmentation.frag"),
                                            {"INST_M_LOC": surface.mesh.defines["INST_M_LOC"]})
                    program.use()
                    camera.set(program)
                    program.set_uniform("color", np.repeat(segmentation[id(surface)], 3) / 255.0)
                    self._draw_plain(surface, program)
                elif lighting is None:
                    program = self._program(("surface.vert", "unlit.frag"), self._material_defines(surface))
                    program.use()
                    camera.set(program)
                    self._draw_material(surface, program)
                elif surface is view.painting and lit.parts:
                    self._draw_painting_parts(view, surface, camera, lighting, lit)
                else:
                    program = lighting.program(surface, lit.shadows, surface is view.painting)
                    program.use()
                    camera.set(program)
                    lighting.bind(program)
                    self._bind_mirror(surface, program)
                    self._draw_material(surface, program)
                self._release_textures()
        finally:
            if stencil:
                GL.glDisable(GL.GL_STENCIL_TEST)
            GL.glUseProgram(0)
        GL.glFlush()

    def _material_defines(self, surface: Surface) -> dict[str, int]:
        defines = dict(surface.mesh.defines)
        if surface.material.texture is not None:
            defines["HAS_BASE_COLOR_TEX"] = 1
            defines.update(surface.material.texture.defines)  # its filter's (programs quirk 15)
        return defines

    def _next_unit(self) -> int:
        unit, self._textures = self._textures, self._textures + 1
        return unit

    def _release_textures(self) -> None:
        """Hand the texture units back for the next surface; the sampler objects bound on them go
        (the next surface's textures keep their own filters)."""
        for unit in range(self._textures):
            GL.glBindSampler(unit, 0)
        self._textures = 0

    def _bind_mirror(self, surface: Surface, program: Program) -> None:
        """In a mirror variant (quirk 8): the painting on the next unit with the trilinear sampler
        (roughness picks a mip level even when the painting itself is drawn bilinear), its size and
        light, and for glass the index of refraction and the occluder's inverse pose."""
        if not any(name in program.defines for name in MIRROR_DEFINES):
            return
        unit = self._next_unit()
        self.painting.texture.bind(unit)
        GL.glBindSampler(unit, self._mirror_sampler)
        program.set_uniform("painting", unit)
        program.set_uniform("painting_half_size", self.painting.half_size)
        program.set_uniform("painting_diffuse", self.painting.diffuse)
        if REFRACTION in program.defines:
            program.set_uniform("material_ior", surface.material.ior)
            program.set_uniform("object_from_world", np.linalg.inv(surface.pose))

    def _draw_plain(self, surface: Surface, program: Program) -> None:
        """Draw ``surface`` with ``program`` bound, back faces culled, no blending, no material."""
        program.set_uniform("M", surface.pose)
        GL.glEnable(GL.GL_CULL_FACE)
        GL.glCullFace(GL.GL_BACK)
        GL.glEnable(GL.GL_BLEND)
        GL.glBlendFunc(GL.GL_ONE, GL.GL_ZERO)
        GL.glPolygonMode(GL.GL_FRONT_AND_BACK, GL.GL_FILL)
        surface.mesh.draw()

    def _bind_material(self, surface: Surface, program: Program) -> None:
        """Bind ``surface``'s pose, texture, material uniforms, blending and culling (back faces)."""
        material = surface.material
        program.set_uniform("M", surface.pose)
        if material.texture is not None:
            unit = self._next_unit()
            material.texture.bind(unit)
            program.set_uniform("material.base_color_texture", unit)
        program.set_uniform("material.emissive_factor", material.factors)
        program.set_uniform("material.base_color_factor", material.base_color)
        program.set_uniform("material.metallic_factor", material.metallic)
        program.set_uniform("material.roughness_factor", material.roughness)
        GL.glEnable(GL.GL_BLEND)
        if material.blend:
            GL.glBlendFunc(GL.GL_SRC_ALPHA, GL.GL_ONE_MINUS_SRC_ALPHA)
        else:
            GL.glBlendFunc(GL.GL_ONE, GL.GL_ZERO)
        GL.glPolygonMode(GL.GL_FRONT_AND_BACK, GL.GL_FILL)
        GL.glEnable(GL.GL_CULL_FACE)
        GL.glCullFace(GL.GL_BACK)

    def _draw_material(self, surface: Surface, program: Program) -> None:
        self._bind_material(surface, program)
        surface.mesh.draw()

    def _draw_painting_parts(self, view: ViewDraws, painting: Surface, camera: "_Camera",
                             lighting: "_PassLighting", lit: "_LitDraw") -> None:
        """Draw the painting once per part, under the part's scissor with its lookup range.

        Parts with a lookup are drawn with the shadowed program; parts without one with the program
        without spot-light shadows, which adds the same lights in the same order in one loop instead
        of three around an empty range (a loop costs every fragment it runs for, even with no trip:
        quirk 6). The parts tile the image, so each pixel is drawn once.
        """
        looked_up = [part for part in lit.parts if part.begin < part.end]
        free = [part for part in lit.parts if part.begin == part.end]
        GL.glEnable(GL.GL_SCISSOR_TEST)
        try:
            for parts, shadows in ((looked_up, True), (free, False)):
                if not parts:
                    continue
                self._release_textures()
                program = lighting.program(painting, shadows, True)
                program.use()
                camera.set(program)
                lighting.bind(program)
                self._draw_under_scissors(painting, program, parts)
        finally:
            GL.glDisable(GL.GL_SCISSOR_TEST)

    def _draw_under_scissors(self, surface: Surface, program: Program, parts: Sequence[PaintingPart]) -> None:
        """Draw ``surface`` with ``program`` once per part, under the part's scissor with its lookup
        range, bound once. The parts are drawn by lookup range, so the range's uniforms change only
        between ranges (each change costs llvmpipe's next draw a constants update); the parts cover
        disjoint pixels, so their order changes none."""
        self._bind_material(surface, program)
        surface.mesh.bind()
        current = None
        for part in sorted(parts, key=lambda p: (p.begin, p.end)):
            # Window rows: drawn upside down (FLIP_Y), image row r is window row r; upright, H - 1 - r.
            y = part.y if FLIP_Y[1, 1] < 0 else self.height - part.y - part.height
            GL.glScissor(part.x, y, part.width, part.height)
            if (part.begin, part.end) != current:
                current = part.begin, part.end
                program.set_uniform("lookup_begin", part.begin)
                program.set_uniform("lookup_end", part.end)
            surface.mesh.draw_bound()
        GL.glBindVertexArray(0)


class _LitDraw:
    """What one lit draw asks of its programs (see :meth:`Passes.draw`)."""

    def __init__(self, shadows: bool, transmittance: bool, n_shadowed: int, shadow_fraction: bool, shadow_free: bool,
                 parts: Sequence[PaintingPart] | None, light_groups: int | None):
        self.shadows, self.transmittance, self.n_shadowed = shadows, transmittance, n_shadowed
        self.shadow_fraction, self.shadow_free = shadow_fraction, shadow_free
        self.parts = list(parts) if parts else None
        self.light_groups = light_groups


class _Camera:
    """A forward pass's camera uniforms: ``V``, ``P`` (flipped) and the camera's world position."""

    def __init__(self, V: np.ndarray, P: np.ndarray, position: np.ndarray):
        self.V, self.P, self.position = V, P, position

    def set(self, program: Program) -> None:
        program.set_uniform("V", self.V)
        program.set_uniform("P", self.P)
        program.set_uniform("cam_pos", self.position)


class _PassLighting:
    """The lighting of one lit pass: computed once, each program's uniforms set once, the lights'
    uniform block filled once per layout (``light_block``; quirk 14), the lighting textures bound
    for every surface (units are context state, which each surface's material binding changes).

    With spot-light shadows the textures are the shadow maps (one array) and, when the pass reads
    them, the transmittance maps: the same layout in every lit draw whatever the number of lights
    (llvmpipe compiles a fragment-shader variant, about 1 s, per layout of bound textures).

    Raises:
        ValueError: more spot lights than the shader has (``MAX_SHADOWED_LIGHTS``).
    """

    def __init__(self, passes: Passes, view: ViewDraws, lit: _LitDraw):
        if len(view.lights) > MAX_SHADOWED_LIGHTS:
            raise ValueError(f"the renderer draws up to {MAX_SHADOWED_LIGHTS} spot lights; got {len(view.lights)}")
        self.passes, self.lit = passes, lit
        self.uniforms: list[tuple[str, Any]] = [
            ("ambient_light", view.ambient), ("n_spot_lights", len(view.lights)),
            ("highlight_spill", float(passes.highlight_spill)),
            ("lookup_begin", 0), ("lookup_end", lit.n_shadowed if lit.shadows else 0)]
        self.textures: list[tuple[Any, str]] = []
        self.lights: dict[str, list[Any]] = defaultdict(list)
        self.count = len(view.lights)
        for light in view.lights:
            pose = light.pose
            scale = 1.0 / max(0.001, np.cos(light.inner_cone) - np.cos(light.outer_cone))
            group = pose if light.group_pose is None else light.group_pose
            members = {"direction": -pose[:3, 2], "position": pose[:3, 3],
                       "group_direction": -group[:3, 2], "group_position": group[:3, 3],
                       "group_size": int(light.group_size), "light_angle_scale": scale,
                       "light_angle_offset": -np.cos(light.outer_cone) * scale,
                       "color": light.color, "intensity": light.intensity,
                       "smooth_falloff": float(light.smooth_falloff)}
            if lit.shadows:
                V, P = passes.matrices(view, light)
                members.update(light_matrix=P.dot(V), shadow_layer=light.layer)
                if passes.light_radius > 0:  # window depth back to depth along the axis; uv per tangent
                    members.update(soft_depth=np.array([P[2, 2], P[2, 3], P[0, 0] / 2, P[1, 1] / 2]),
                                   soft_reach=float(light.soft_reach))
            for member, value in members.items():
                self.lights[member].append(value)
        if lit.shadows:
            self.textures.append((passes.shadow_maps, "spot_shadow_maps"))
            if passes.light_radius > 0:
                self.uniforms.append(("light_radius", float(passes.light_radius)))
                self.textures.append((passes.shadow_maps, "spot_shadow_depths"))
            if lit.transmittance:  # the transmittance variant (same layout in every draw that uses it)
                self.textures.append((passes.transmittance, "transmittance_maps"))
                self.uniforms.append(("transmittance_layout", np.array(passes.transmittance.layout, np.int32)))
        self._programs: set[int] = set()  # ids of the programs holding this pass's uniforms
        self._filled: set[bool] = set()  # the light block layouts (shadows or not) filled this pass

    def program(self, surface: Surface, shadows: bool, painting: bool) -> Program:
        """The surface program for ``surface`` in this pass: with or without spot-light ``shadows``,
        and its variants (quirks 6-10)."""
        lit = self.lit
        defines = self.passes._material_defines(surface)
        defines["MAX_SPOT_LIGHTS"] = MAX_SHADOWED_LIGHTS
        if shadows:
            defines["SPOT_LIGHT_SHADOWS"] = 1
            if lit.transmittance:
                defines["TRANSMITTANCE_SHADOWS"] = 1
        elif painting and lit.light_groups is not None:
            defines["LIGHT_GROUPS"] = lit.light_groups
        if surface.material.mirror and self.passes.painting is not None:
            defines[surface.material.mirror] = 1
        if lit.shadow_fraction:
            defines["SHADOW_FRACTION"] = 1
        if lit.shadow_free:
            defines["SHADOW_FREE"] = 1
        return self.passes._program(("surface.vert", "surface.frag"), defines)

    def bind(self, program: Program) -> None:
        """Bind this pass's lighting for one surface drawn with ``program`` (bound)."""
        first = id(program) not in self._programs
        if first:
            self._programs.add(id(program))
            shadows = "SPOT_LIGHT_SHADOWS" in program.defines
            if shadows not in self._filled:
                self.passes._light_blocks.upload(self.lights, self.count, shadows)
                self._filled.add(shadows)
            for name, value in self.uniforms:
                program.set_uniform(name, value)
        for texture, name in self.textures:
            unit = self.passes._next_unit()
            GL.glActiveTexture(GL.GL_TEXTURE0 + unit)
            texture.bind()
            if name == "spot_shadow_depths":  # the same maps without their depth comparison
                GL.glBindSampler(unit, self.passes._depth_sampler)
            if first:
                program.set_uniform(name, unit)
