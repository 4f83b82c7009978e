"""Every override of pyrender in one place: what the renderer changes in pyrender, and why.

* :class:`GLRenderer` (a ``pyrender.Renderer``): a long-lived context drawing many small scenes
  into its own framebuffer, with pooled uploads, every spot light shading, any power-of-two shadow
  map, fitted shadow frusta, transmittance maps for transparent casters, our own shader programs
  (``render.programs``: the cache, our GLSL and its quirks) and no GL call at garbage collection
  (its docstring lists each change);
* :class:`RankedNode`: scene nodes hashed by insertion rank, so lights are summed in a fixed order
  (:func:`ranked`); :class:`ShadowedSpotLight`: a spot light with a layer of the shadow-map array.

``scene_graph.FlatScene`` and ``mirror.SurfaceMaterial`` subclass pyrender's scene and material too.
"""

from __future__ import annotations

import ctypes
from collections import defaultdict
from typing import Any, Sequence

import numpy as np
import pyrender
from OpenGL import GL
from pyrender.constants import MAX_N_LIGHTS, ProgramFlags, RenderFlags

from ..render_choices import MAX_SHADOWED_LIGHTS
from ..timing import timed
from .footprints import PaintingPart
from .framebuffer import FLIP_Y, Framebuffer
from .mirror import MIRROR_DEFINES, REFRACTION, PaintingMirror
from .programs import Program, ProgramCache
from .shadow_array import ShadowMapArray, TexelBox
from .transmittance import TransmittanceMaps, vertex_defines
from .light_block import LightBlocks
from .uniforms import set_uniform_array
from .visibility import bounds_corners, map_texel_box

__all__ = ["UNROLLED_LIGHT_GROUPS", "GLRenderer", "RankedNode", "ShadowedSpotLight", "add_node",
           "frustum_projection", "light_group_count", "ranked"]


def frustum_projection(frustum: np.ndarray) -> np.ndarray:
    """OpenGL projection ``(4, 4)`` of a frustum from :func:`~.visibility.light_frustum`.

    The frustum is in the OpenCV frame (y down, z forward); the light's node pose is the same frame
    turned to OpenGL's (``_gl_pose``: y up, looking along -z), so its window's y bounds swap sign.
    This is ``glFrustum(x0 n, x1 n, -y1 n, -y0 n, n, f)``.
    """
    x0, x1, y0, y1, n, f = frustum
    return np.array([
        [2 / (x1 - x0), 0.0, (x1 + x0) / (x1 - x0), 0.0],
        [0.0, 2 / (y1 - y0), -(y1 + y0) / (y1 - y0), 0.0],
        [0.0, 0.0, -(f + n) / (f - n), -2 * f * n / (f - n)],
        [0.0, 0.0, -1.0, 0.0],
    ])


_BOTTOM_ROW = (0.0, 0.0, 0.0, 1.0)
"""The bottom row of a pose."""

UNROLLED_LIGHT_GROUPS = 4
"""The most light groups the painting's program without lookups adds written out rather than in a loop
(the copies under ``#elif defined(LIGHT_GROUPS)`` in ``shaders/surface.frag``); a view with more gets the loop. A renderer takes
it at construction (``GLRenderer.unrolled_light_groups``)."""


class RankedNode(pyrender.Node):
    """A scene node whose hash is its insertion rank in the scene, not its memory address, and
    whose pose is stored as given.

    pyrender keeps nodes in sets; address-based hashes would make the order of anything iterated
    from them change from one render to the next. The lights are summed in rank order
    (:func:`ranked`), which ``render.plan``'s order of shadowed emitters relies on.

    pyrender decomposes a pose into a quaternion, scale and translation whenever it is set (half a
    millisecond, about 20 times per sample), although drawing reads only the pose itself; here
    the decomposition is made only if ``rotation``, ``scale`` or ``translation`` is read or set.
    """

    def __init__(self, rank: int, **kwargs: Any):
        super().__init__(**kwargs)
        self._rank = rank

    def __hash__(self) -> int:
        return self._rank

    @property
    def matrix(self) -> np.ndarray:
        """``(4, 4)`` float object-to-parent pose (a copy, as pyrender's)."""
        return pyrender.Node.matrix.fget(self)

    @matrix.setter
    def matrix(self, value: np.ndarray) -> None:
        value = np.asanyarray(value)
        # np.allclose's test (NaN fails it) in Python floats: a fifth of its cost, about 9 poses per view
        if value.shape != (4, 4) or not all(abs(a - b) <= 1e-8 + 1e-5 * b for a, b in zip(value[3].tolist(), _BOTTOM_ROW)):
            raise ValueError(f"matrix: expected a (4, 4) pose with bottom row [0, 0, 0, 1], got {value!r}")
        self._rotation = self._scale = self._translation = None  # derived on demand (_decompose)
        self._matrix = value

    def _decompose(self) -> None:
        if self._rotation is None:
            self._rotation, self._scale, self._translation = (
                self._q_from_m(self._matrix), self._s_from_m(self._matrix), self._t_from_m(self._matrix))

    def _derived(field: str) -> property:  # noqa: N805 (a helper of the class body, deleted below)
        inherited = getattr(pyrender.Node, field)

        def get(self: "RankedNode") -> np.ndarray:
            self._decompose()
            return inherited.fget(self)

        def set_(self: "RankedNode", value: np.ndarray) -> None:
            if self._matrix is not None:
                self._decompose()
            inherited.fset(self, value)

        return property(get, set_, doc=inherited.__doc__)

    rotation = _derived("rotation")
    scale = _derived("scale")
    translation = _derived("translation")
    del _derived


def ranked(nodes: set[pyrender.Node]) -> list[pyrender.Node]:
    """A scene's :class:`RankedNode` s in insertion order: the order the shader sums the lights in
    and ``render.plan`` puts the shadowed emitters first in. Iterating the set itself is not that
    order: a set of small-integer hashes iterates in hash-table order, which wraps around when
    ranks reach the table's size (ranks 5..8 in a table of 8 iterate as 8, 5, 6, 7)."""
    return sorted(nodes, key=hash)


def light_group_count(scene: pyrender.Scene) -> int:
    """How many light groups the shader adds for ``scene``'s spot lights: in their order, each
    group's first light says how many lights it spans (``ShadowedSpotLight.group_size``, quirk 13)."""
    lights = [node.light for node in ranked(scene.spot_light_nodes)]
    count = k = 0
    while k < len(lights):
        count += 1
        k += lights[k].group_size
    return count


def add_node(scene: pyrender.Scene, pose: np.ndarray | None = None, **obj: Any) -> pyrender.Node:
    """Add ``mesh=``, ``light=`` or ``camera=`` to ``scene`` at ``pose`` as a :class:`RankedNode`."""
    node = RankedNode(len(scene.nodes), matrix=pose, **obj)
    scene.add_node(node)
    return node


class ShadowedSpotLight(pyrender.SpotLight):
    """A pyrender spot light whose shadow map is layer :attr:`shadow_layer` of the renderer's
    :class:`~.shadow_array.ShadowMapArray` (pyrender's ``shadow_texture`` stays unused), with
    Blender's smoothstep falloff between its cones when :attr:`smooth_falloff` (``scene.Light``),
    the reach of its soft shadow lookups (:attr:`soft_reach`), and the group of emitters it is
    shaded with (:attr:`group_size`, :attr:`group_pose`; quirk 13)."""

    def __init__(self, shadow_layer: int, smooth_falloff: bool = False, **kwargs: Any):
        super().__init__(**kwargs)
        self.shadow_layer = shadow_layer
        self.smooth_falloff = smooth_falloff
        self.soft_reach = 0.0
        """How far its soft lookups search the map (``plan.soft_reach``; tangent units)."""
        self.group_size = 1
        """How many emitters, this one and the next in the shader's order, are shaded together."""
        self.group_pose: np.ndarray | None = None
        """``(4, 4)`` pose (OpenGL frame) the group is shaded from, aimed as its emitters are; ``None``:
        the light's own."""


def _posed_primitives(scene: pyrender.Scene,
                      nodes: Sequence[pyrender.Node]) -> list[tuple[pyrender.Primitive, np.ndarray]]:
    """``(primitive, pose)`` for every primitive of ``nodes`` (mesh nodes of ``scene``), in their order."""
    return [(primitive, scene.get_pose(node)) for node in nodes for primitive in node.mesh.primitives]


class GLRenderer(pyrender.Renderer):
    """pyrender's renderer, adapted to a long-lived context that draws many small scenes.

    * programs come from ``programs.ProgramCache`` (one per context, our shaders);
    * :meth:`_update_context` uploads what is new and frees only textures no longer used (the
      previous painting, once a draw uses another); pooled meshes and shadow maps stay uploaded
      until :meth:`delete`;
    * every spot light can shade, with or without shadows (pyrender limits unshadowed lights
      to the 4 nearest); the lights reach the shaders as one uniform block per pass (``light_block``);
    * shadow maps may be any power-of-two size, drawn with the fitted frusta of :attr:`shadow_frusta`;
    * forward passes draw upside down into its own :class:`Framebuffer` (single-sampled unless a pass asks for its multisampled buffers) (EGL
      contexts have no default framebuffer; ``framebuffer`` explains the orientation);
    * transparent casters tint and lighten their shadows through transmittance maps instead of
      darkening the depth maps (``render.transmittance``);
    * reflective and glass occluders are drawn with the program variant of their material's
      ``mirror`` define, with the painting of :attr:`painting` bound (``render.mirror``);
    * the painting's lit draw can be split into screen rectangles, each with only the shadow
      lookups it needs (``render.footprints``; :meth:`draw`'s ``painting_parts``);
    * garbage collection issues no GL call (pyrender's ``__del__`` deletes its objects by id in
      whatever context is current, which may be another renderer's): the objects die with
      their context, which :class:`~.renderer.SceneRenderer` destroys.
    """

    def __init__(self, width: int, height: int, shadow_map_size: int, shadow_taps: int, samples: int = 1,
                 outputs: int = 1, clear_written_texels: bool = True, highlight_spill: bool = True,
                 light_radius: float = 0.0):
        super().__init__(width, height)
        self._program_cache = ProgramCache(shadow_taps)
        self._target = Framebuffer(width, height, samples, outputs)
        self._outputs = 1  # colour outputs of the current draw (see draw's shadow_free)
        self.shadow_map_size = shadow_map_size
        self.shadow_maps = ShadowMapArray(shadow_map_size)
        """The :class:`ShadowedSpotLight` s' shadow maps, one layer each."""
        self._shadow_frusta: dict[pyrender.Node, np.ndarray] = {}
        self._light_matrices: dict[pyrender.Node, tuple[np.ndarray, np.ndarray]] = {}
        self.transmittance = TransmittanceMaps(shadow_map_size // 2)
        self.clear_written_texels = clear_written_texels
        """Clear only the texels of a shadow or transmittance map that its last draw may have
        written (``shadow_array``); false: every map whole."""
        self._shadow_writes: TexelBox = (0, 0, shadow_map_size, shadow_map_size)  # of the next shadow pass
        self.highlight_spill = highlight_spill
        self.light_radius = light_radius
        """Every emitter's radius (painting units); above 0 the lookups are soft (``shadow_taps`` 0)."""
        self._depth_sampler = GL.glGenSamplers(1)  # the shadow maps read as depths (soft lookups' search)
        for name, value in ((GL.GL_TEXTURE_MIN_FILTER, GL.GL_NEAREST), (GL.GL_TEXTURE_MAG_FILTER, GL.GL_NEAREST),
                            (GL.GL_TEXTURE_WRAP_S, GL.GL_CLAMP_TO_EDGE), (GL.GL_TEXTURE_WRAP_T, GL.GL_CLAMP_TO_EDGE),
                            (GL.GL_TEXTURE_COMPARE_MODE, GL.GL_NONE)):
            GL.glSamplerParameteri(self._depth_sampler, name, value)
        self._depth_unit: int | None = None  # texture unit the depth sampler is bound to during a draw
        """Over-exposed light spills into the other channels (a blown-out red turns white); false:
        each channel clips at white on its own."""
        self._filtered = False  # whether the current draw's lights have transmittance maps
        self._n_shadowed = 0  # shadow-casting spot lights of the current draw (see draw)
        self._split: tuple[Any, Sequence[PaintingPart], pyrender.Scene] | None = None  # (painting primitive, parts, scene) of a lit draw
        self._painting_primitive: pyrender.Primitive | None = None  # of the current draw
        self._stencil = False  # whether the current draw writes the stencil (see draw's stencil)
        self._light_groups: int | None = None  # the current draw's, if at most unrolled_light_groups
        self.unrolled_light_groups = UNROLLED_LIGHT_GROUPS  # 0: the painting's program keeps the loop
        self._pass_lighting: tuple[list, list, list] | None = None  # see _bind_lighting
        self._light_blocks = LightBlocks()
        self._filled_blocks: set[bool] = set()  # the light block layouts (shadows or not) filled this pass
        self._lit_programs: set[Program] = set()
        self.painting: PaintingMirror | None = None
        """The painting that reflective and glass occluders show in the next lit draws."""
        self._mirror_sampler = GL.glGenSamplers(1)  # trilinear whatever the painting's own filter
        for name, value in ((GL.GL_TEXTURE_MIN_FILTER, GL.GL_LINEAR_MIPMAP_LINEAR), (GL.GL_TEXTURE_MAG_FILTER, GL.GL_LINEAR),
                            (GL.GL_TEXTURE_WRAP_S, GL.GL_CLAMP_TO_EDGE), (GL.GL_TEXTURE_WRAP_T, GL.GL_CLAMP_TO_EDGE)):
            GL.glSamplerParameteri(self._mirror_sampler, name, value)
        self._mirror_unit: int | None = None  # texture unit the sampler is bound to during a draw


    def _update_context(self, scene: pyrender.Scene, flags: int) -> None:
        for mesh in scene.meshes - self._meshes:
            for primitive in mesh.primitives:
                primitive._add_to_context()
        self._meshes |= scene.meshes
        textures = {t for m in scene.meshes for p in m.primitives for t in p.material.textures}
        if textures:  # a draw without textures (the opacity draw) keeps the painting's uploaded
            for texture in textures - self._mesh_textures:
                texture._add_to_context()
            for texture in self._mesh_textures - textures:
                texture.delete()
            self._mesh_textures = textures

    def __del__(self) -> None:
        pass

    def _bind_lighting(self, scene, program, node, flags) -> None:
        """Bind the lights (the renderer makes spot lights only) for one primitive's draw.

        pyrender computes every light's uniforms and light matrix again for every primitive and
        sets them again, although a program keeps its uniform values: here they are computed
        once per forward pass (:meth:`_light_uniforms`); the lights go into the uniform block of the
        program's layout once per pass (``light_block``), the other uniforms are set once per program
        and pass. Texture units are context state, which each primitive's material binding changes
        after them, so the lighting textures are bound again for every primitive.
        """
        if self._pass_lighting is None:
            self._pass_lighting = self._light_uniforms(scene, flags)
        uniforms, textures, lights = self._pass_lighting
        first = program not in self._lit_programs
        if first:
            self._lit_programs.add(program)
            shadows = "SPOT_LIGHT_SHADOWS" in program.defines
            if shadows not in self._filled_blocks:
                self._light_blocks.upload(lights, len(scene.spot_light_nodes), shadows)
                self._filled_blocks.add(shadows)
            for name, value in uniforms:
                program.set_uniform(name, value)
        for texture, name in textures:
            unit = self._get_next_active_texture()
            GL.glActiveTexture(GL.GL_TEXTURE0 + unit)
            texture._bind()
            if name == "spot_shadow_depths":  # the same maps without their depth comparison
                self._depth_unit = unit
                GL.glBindSampler(unit, self._depth_sampler)
            if first:
                program.set_uniform(name, unit)

    def _light_uniforms(self, scene: pyrender.Scene,
                        flags: int) -> tuple[list[tuple[str, Any]], list[tuple[Any, str]], dict[str, list[Any]]]:
        """The lighting uniforms of a forward pass, as pyrender's ``_bind_lighting`` sets them, its
        textures and its lights: ``([(uniform, value)], [(texture, sampler uniform)], {member:
        [value per light]})``, textures in unit order, the lights in the shader's order, as
        ``light_block`` packs them.

        With spot-light shadows the textures are the shadow maps (one array) and, when the pass
        reads them, the transmittance maps: the same layout in every lit draw whatever the number
        of lights (llvmpipe compiles a fragment-shader variant, about 1 s, per layout of bound
        textures).

        Raises:
            ValueError: the scene holds a light that is not a spot light, or more spot lights
                than the shader has (``MAX_SHADOWED_LIGHTS``).
        """
        spots = scene.spot_light_nodes
        if len(scene.light_nodes) != len(spots) or len(spots) > MAX_SHADOWED_LIGHTS:
            raise ValueError(f"the renderer draws up to {MAX_SHADOWED_LIGHTS} spot lights and no other kind; "
                             f"got {len(spots)} spot lights of {len(scene.light_nodes)} lights")
        shadowed = bool(flags & RenderFlags.SHADOWS_SPOT)
        uniforms: list[tuple[str, Any]] = [("ambient_light", scene.ambient_light), ("n_spot_lights", len(spots)),
                                           ("highlight_spill", float(self.highlight_spill)),
                                           ("lookup_begin", 0), ("lookup_end", self._n_shadowed if shadowed else 0)]
        textures: list[tuple[Any, str]] = []
        lights: dict[str, list[Any]] = defaultdict(list)
        for light_node in ranked(scene.light_nodes):
            light, pose = light_node.light, scene.get_pose(light_node)
            scale = 1.0 / max(0.001, np.cos(light.innerConeAngle) - np.cos(light.outerConeAngle))
            group = pose if light.group_pose is None else light.group_pose
            members = {"direction": -pose[:3, 2], "position": pose[:3, 3],
                       "group_direction": -group[:3, 2], "group_position": group[:3, 3],
                       "group_size": int(light.group_size), "light_angle_scale": scale,
                       "light_angle_offset": -np.cos(light.outerConeAngle) * scale,
                       "color": light.color, "intensity": light.intensity,
                       "smooth_falloff": float(light.smooth_falloff)}
            if shadowed:
                V, P = self._get_light_cam_matrices(scene, light_node, flags)
                members.update(light_matrix=P.dot(V), shadow_layer=light.shadow_layer)
                if self.light_radius > 0:  # window depth back to depth along the axis; uv per tangent
                    members.update(soft_depth=np.array([P[2, 2], P[2, 3], P[0, 0] / 2, P[1, 1] / 2]),
                                   soft_reach=float(light.soft_reach))
            for member, value in members.items():
                lights[member].append(value)
        if shadowed:
            textures.append((self.shadow_maps, "spot_shadow_maps"))
            if self.light_radius > 0:
                uniforms.append(("light_radius", float(self.light_radius)))
                textures.append((self.shadow_maps, "spot_shadow_depths"))
            if self._filtered:  # the transmittance variant (same layout in every draw that uses it)
                textures.append((self.transmittance, "transmittance_maps"))
                uniforms.append(("transmittance_layout", np.array(self.transmittance.layout, np.int32)))
        return uniforms, textures, lights

    def _get_primitive_program(self, primitive, flags, program_flags):
        """pyrender's program choice; a lit occluder with a ``mirror`` material gets that variant, and
        the painting the variant for the draw's number of light groups (``ProgramCache.light_groups``)."""
        self._program_cache.mirror = getattr(primitive.material, "mirror", None) if self.painting else None
        self._program_cache.light_groups = self._light_groups if primitive is self._painting_primitive else None
        try:
            return super()._get_primitive_program(primitive, flags, program_flags)
        finally:
            self._program_cache.mirror = self._program_cache.light_groups = None

    def _bind_and_draw_primitive(self, primitive, pose, program, flags) -> None:
        """pyrender's draw, split into the painting's parts for the painting of a lit draw that has
        them (:meth:`_draw_parts`); in a quirk-8 variant, the painting is bound first (its texture on the next
        unit with a trilinear sampler, so roughness can pick a mip level even when the painting
        itself is drawn bilinear), with its size and light and the occluder's index and inverse pose."""
        if any(name in program.defines for name in MIRROR_DEFINES):
            self._bind_texture(self.painting.texture, "painting", program)
            self._mirror_unit = self._texture_alloc_idx - 1
            GL.glBindSampler(self._mirror_unit, self._mirror_sampler)
            program.set_uniform("painting_half_size", self.painting.half_size)
            program.set_uniform("painting_diffuse", self.painting.diffuse)
            if REFRACTION in program.defines:
                program.set_uniform("material_ior", primitive.material.ior)
                program.set_uniform("object_from_world", np.linalg.inv(pose))
        if self._stencil:
            GL.glStencilFunc(GL.GL_ALWAYS, int(primitive is self._painting_primitive), 0xFF)
        if self._split is not None and primitive is self._split[0]:
            self._draw_parts(primitive, pose, program, flags, *self._split[1:])
        else:
            super()._bind_and_draw_primitive(primitive, pose, program, flags)

    def _draw_parts(self, primitive, pose, program, flags, parts: Sequence[PaintingPart], scene: pyrender.Scene) -> None:
        """Draw ``primitive`` once per part, under the part's scissor with its lookup range.

        Parts with a lookup are drawn with ``program``; parts without one with the program pyrender
        gives the painting without spot-light shadows, which adds the same lights in the same order
        in one loop instead of three around an empty range (a loop costs every fragment it runs
        for, even with no trip: quirk 6). The parts tile the image, so each pixel is drawn once.
        """
        looked_up = [part for part in parts if part.begin < part.end]
        free = [part for part in parts if part.begin == part.end]
        GL.glEnable(GL.GL_SCISSOR_TEST)
        try:
            if looked_up:
                self._draw_under_scissors(primitive, pose, program, flags, looked_up)
            if free:
                self._reset_active_textures()  # the units go to the other program's textures, in the same order
                free_program = self._get_primitive_program(primitive, flags & ~RenderFlags.SHADOWS_SPOT,
                                                           ProgramFlags.USE_MATERIAL)
                free_program._bind()
                V, P = self._get_camera_matrices(scene)
                free_program.set_uniform("V", V)
                free_program.set_uniform("P", P)
                free_program.set_uniform("cam_pos", scene.get_pose(scene.main_camera_node)[:3, 3])
                self._bind_lighting(scene, free_program, None, flags)
                self._draw_under_scissors(primitive, pose, free_program, flags, free)
        finally:
            GL.glDisable(GL.GL_SCISSOR_TEST)
            program._bind()  # its lookup range back to every shadowed light, for the next primitives
            program.set_uniform("lookup_begin", 0)
            program.set_uniform("lookup_end", self._n_shadowed)

    def _draw_under_scissors(self, primitive, pose, program, flags, parts: Sequence[PaintingPart]) -> None:
        """Draw ``primitive`` with ``program`` once per part, under the part's scissor with its lookup
        range: the first draw is pyrender's (it binds the material), the others draw the same
        primitive again, bound once. The parts are drawn by lookup range, so the range's uniforms
        change only between ranges (each change costs llvmpipe's next draw a constants update); the
        parts cover disjoint pixels, so their order changes none."""
        current = None
        for k, part in enumerate(sorted(parts, key=lambda p: (p.begin, p.end))):
            # Window rows: drawn upside down (FLIP_Y), image row r is window row r; upright, H - 1 - r.
            y = part.y if FLIP_Y[1, 1] < 0 else self.viewport_height - part.y - part.height
            GL.glScissor(part.x, y, part.width, part.height)
            if (part.begin, part.end) != current:
                current = part.begin, part.end
                program.set_uniform("lookup_begin", part.begin)
                program.set_uniform("lookup_end", part.end)
            if k == 0:
                super()._bind_and_draw_primitive(primitive, pose, program, flags)  # unbinds the primitive
                primitive._bind()
            elif primitive.indices is not None:
                GL.glDrawElements(primitive.mode, primitive.indices.size, GL.GL_UNSIGNED_INT, ctypes.c_void_p(0))
            else:
                GL.glDrawArrays(primitive.mode, 0, len(primitive.positions))
        primitive._unbind()

    def _sorted_mesh_nodes(self, scene: pyrender.Scene) -> list[pyrender.Node]:
        """The draw order of every pass: the opaque meshes nearest first, then the blended ones
        farthest first (pyrender's order, which draws the opaque ones farthest first too).

        Opaque draws do not blend, so a pixel keeps its nearest fragment's colour in any order; drawn
        nearest first, the depth test rejects the fragments an occluder hides (the painting's, whose
        lookups are dearest) before they are shaded. Blended meshes keep pyrender's order, which
        their blending depends on. Distances are from the camera to each node's origin, as in pyrender.
        """
        camera = scene.get_pose(scene.main_camera_node)[:3, 3]
        distance = {node: np.linalg.norm(scene.get_pose(node)[:3, 3] - camera) for node in scene.mesh_nodes}
        opaque = sorted((node for node in scene.mesh_nodes if not node.mesh.is_transparent), key=distance.__getitem__)
        blended = sorted((node for node in scene.mesh_nodes if node.mesh.is_transparent), key=lambda n: -distance[n])
        return opaque + blended

    def _reset_active_textures(self) -> None:
        """pyrender's reset after each primitive, and the painting's and the depth sampler unbound
        (the units go to the next primitive's textures, which keep their own filters)."""
        for unit in (self._mirror_unit, self._depth_unit):
            if unit is not None:
                GL.glBindSampler(unit, 0)
        self._mirror_unit = self._depth_unit = None
        super()._reset_active_textures()

    def _compute_max_n_lights(self, flags: int) -> list[int]:
        return [MAX_N_LIGHTS, MAX_SHADOWED_LIGHTS, MAX_N_LIGHTS]

    def _configure_forward_pass_viewport(self, flags) -> None:
        """pyrender's forward-pass state (it binds framebuffer 0 for drawing), then our framebuffer;
        the pass's lighting is not computed yet."""
        super()._configure_forward_pass_viewport(flags)
        self._target.begin_drawing(self._outputs)
        if self._stencil:  # cleared to 0; each fragment that passes the depth test writes its draw's value
            GL.glStencilMask(0xFF)
            GL.glClearStencil(0)
            GL.glClear(GL.GL_STENCIL_BUFFER_BIT)
            GL.glEnable(GL.GL_STENCIL_TEST)
            GL.glStencilOp(GL.GL_KEEP, GL.GL_KEEP, GL.GL_REPLACE)
        self._pass_lighting = None  # computed at the pass's first lit draw (_bind_lighting)
        self._lit_programs = set()  # programs holding the pass's lighting uniforms
        self._filled_blocks = set()

    def _get_camera_matrices(self, scene: pyrender.Scene) -> tuple[np.ndarray, np.ndarray]:
        """pyrender's view and projection matrices, the projection flipped to draw upside down."""
        V, P = super()._get_camera_matrices(scene)
        return V, FLIP_Y @ P

    @property
    def shadow_frusta(self) -> dict[pyrender.Node, np.ndarray]:
        """Light node -> fitted frustum (``visibility.light_frustum``) for the next draws; a light
        not in it gets pyrender's frustum, fitted to its cone. Assign a new dict for each view."""
        return self._shadow_frusta

    @shadow_frusta.setter
    def shadow_frusta(self, frusta: dict[pyrender.Node, np.ndarray]) -> None:
        self._shadow_frusta = frusta
        self._light_matrices = {}

    def _get_light_cam_matrices(self, scene, light_node, flags) -> tuple[np.ndarray, np.ndarray]:
        """The light's view and projection: pyrender's (a square frustum 2 outer cone + pi / 16
        wide, depths from 1 % to 10x the scene's size), or the fitted :attr:`shadow_frusta` one.

        The shadow pass and the lit shader's lookup both take the matrices from here, so the map
        is always read with the projection it was drawn with. They are computed once per light
        node until :attr:`shadow_frusta` is assigned again (a node belongs to one scene, whose
        meshes, and so pyrender's frustum, are all added before its first draw).
        """
        if light_node not in self._light_matrices:
            self._light_matrices[light_node] = self._light_view_projection(scene, light_node, flags)
        return self._light_matrices[light_node]

    def _light_view_projection(self, scene, light_node, flags) -> tuple[np.ndarray, np.ndarray]:
        V, P = super()._get_light_cam_matrices(scene, light_node, flags)
        frustum = self.shadow_frusta.get(light_node)
        if frustum is None:
            return V, P
        # The fitted window and far plane, but pyrender's near plane (closer than any caster): the
        # lit shader's depth bias is a constant in window depth over w, about b z (f - n) / (f n)
        # painting units along the ray, so a tight near (~50x farther) would shrink it ~50x and
        # curved occluders would shadow themselves in stripes (acne). 24-bit depth still
        # resolves about 1e-5 painting units at the painting with this near.
        near = light_node.light._get_shadow_camera(scene.scale).znear
        return V, frustum_projection(np.array([*frustum[:4], min(near, frustum[4]), frustum[5]]))

    def _configure_shadow_mapping_viewport(self, light: ShadowedSpotLight, flags: int) -> None:
        """pyrender's shadow-pass state, drawing into the light's layer of :attr:`shadow_maps`,
        cleared, for a pass that writes only the texels of :attr:`_shadow_writes`."""
        self._configure_shadow_framebuffer()
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, self._shadow_fb)
        GL.glDrawBuffer(GL.GL_NONE)
        GL.glReadBuffer(GL.GL_NONE)
        GL.glDepthMask(GL.GL_TRUE)  # before the clear: the mask applies to it
        self.shadow_maps.attach(light.shadow_layer, self._shadow_writes)
        GL.glViewport(0, 0, self.shadow_map_size, self.shadow_map_size)
        GL.glEnable(GL.GL_DEPTH_TEST)
        GL.glDepthFunc(GL.GL_LESS)
        GL.glDepthRange(0.0, 1.0)
        GL.glDisable(GL.GL_CULL_FACE)
        GL.glDisable(GL.GL_BLEND)

    def _caster_corners(self, casters: Sequence[tuple[pyrender.Primitive, np.ndarray]]) -> np.ndarray | None:
        """``(8 N, 3)`` world corners of the boxes of ``casters`` (``(primitive, pose)`` pairs), the same
        for every light of a view; ``None`` (not bounded: every texel may be written) for instanced
        primitives or without ``clear_written_texels``."""
        if not self.clear_written_texels or any(p.poses is not None for p, _ in casters):
            return None
        corners = [bounds_corners(primitive.bounds, pose) for primitive, pose in casters]
        return np.concatenate(corners) if corners else np.zeros((0, 3))

    def _caster_texels(self, scene: pyrender.Scene, light_node: pyrender.Node, flags: int,
                       corners: np.ndarray | None, size: int) -> TexelBox:
        """The texels of a ``size``-texel map from ``light_node`` that drawing casters with the box
        ``corners`` of :meth:`_caster_corners` may write (``None``: the whole map)."""
        if corners is None:
            return 0, 0, size, size
        V, P = self._get_light_cam_matrices(scene, light_node, flags)
        return map_texel_box(corners, P @ V, size)

    def _transmittance_pass(self, scene: pyrender.Scene, light_node: pyrender.Node, k: int,
                            casters: list[tuple[pyrender.Primitive, np.ndarray]], corners: np.ndarray | None,
                            flags: int) -> None:
        """Draw the transparent ``casters`` (``(primitive, pose)`` pairs, box ``corners`` of
        :meth:`_caster_corners`) into tile ``k`` of the transmittance maps, from ``light_node`` with
        the light matrix of its depth map."""
        V, P = self._get_light_cam_matrices(scene, light_node, flags)
        writes = self._caster_texels(scene, light_node, flags, corners, self.transmittance.tile)
        self.transmittance.draw_tile(k, V, P, scene.get_pose(light_node)[:3, 3], casters,
                                     self._transmittance_program, writes)

    def _transmittance_program(self, primitive: pyrender.Primitive):
        program = self._program_cache.get_program("mesh.vert", "transmittance.frag",
                                                  defines=vertex_defines(primitive))
        if not program._in_context():
            program._add_to_context()
        return program

    def draw(self, scene: pyrender.Scene, flags: int, seen: set, casters: set = frozenset(),
             transmitting: set = frozenset(), shadowed: set = frozenset(), seg_node_map: dict | None = None,
             timings: dict[str, float] | None = None, step: str = "colour", stale: set | None = None,
             painting_parts: tuple[pyrender.Node, Sequence[PaintingPart]] | None = None,
             shadow_fraction: bool = False, shadow_free: bool = False, stencil: bool = False) -> np.ndarray:
        """Draw ``scene`` into the renderer's framebuffer and read it back as ``(H, W, 4)`` uint8
        (with ``shadow_free``, ``(2, H, W, 4)``: the colour, then the colour with no light blocked).

        Args:
            flags: pyrender render flags; with ``SHADOWS_SPOT`` every light gets a shadow map.
            seen: mesh nodes the camera sees.
            casters: mesh nodes that cast shadows: those of ``transmitting`` go into the
                transmittance maps (drawn and looked up only when there is one), the others into
                the depth maps.
            transmitting: the blended (transparent) casters whose shadows let light through,
                tinted (``scene.Material.opaque_shadow`` false).
            shadowed: light nodes that get a shadow map and lookup (with ``SHADOWS_SPOT``); they
                must be the first spot lights in the scene's order.
            seg_node_map: node -> grey level, for ``RenderFlags.SEG`` draws.
            timings: if given, seconds are added to ``"upload"`` (new textures and meshes),
                ``"shadow"`` (shadow-map passes), ``step`` (the forward pass) and ``"readback"``.
            step: the name the forward pass is timed under (``"colour"``, ``"mask"``, ``"opacity"``,
                ``"label"``).
            stale: the nodes of ``shadowed`` whose shadow maps are drawn (default: all); the
                others' maps must already hold what this scene would draw into them.
            painting_parts: ``(painting node, parts)``: with ``SHADOWS_SPOT``, the painting is drawn
                once per part, each with only its lookups (``render.footprints``).
            shadow_fraction: lit draws output, in every colour channel, the fraction of the direct
                light the occluders block (the shadow-mask draw; ``SHADOW_FRACTION``, quirk 9). It
                reads the shadow and transmittance maps the colour pass of the same scene just drew:
                none is drawn again (``stale`` is ignored).
            shadow_free: with ``SHADOWS_SPOT``, lit draws also output the colour with every
                light unblocked (``SHADOW_FREE``, quirk 10); the renderer's framebuffer must
                have been made with two outputs.
            stencil: the pass also leaves in the stencil buffer, per pixel, 1 where the fragment
                that kept the pixel's depth is the painting's (the primitive of ``painting_parts``)
                and 0 elsewhere (:meth:`.framebuffer.Framebuffer.read_stencil`): a single-sampled
                pass only (no antialiasing).

        Where GL time lands: pyrender ends every pass with ``glFlush``, and llvmpipe with
        ``LP_NUM_THREADS=0`` rasterises the queued draws in this thread before a flush returns,
        so a pass's time is its own. When timing, each step also ends with ``glFinish`` (a no-op
        here, but it keeps asynchronous drivers, e.g. a GPU under EGL, from billing the draws
        to ``readback``); it does not change a pixel.
        """
        if stencil and self._target.samples > 1:
            raise ValueError("stencil: needs a single-sampled colour pass; this renderer draws it with "
                             f"{self._target.samples} samples per pixel (antialias)")
        if stencil and painting_parts is None:
            raise ValueError("stencil: needs painting_parts, whose node is the painting it marks")
        with timed(timings, "upload", GL.glFinish):
            self._update_context(scene, flags)
        filters = sorted(casters & transmitting, key=hash)  # hash: rank in the scene
        self._filtered = bool(filters) and bool(flags & RenderFlags.SHADOWS_SPOT)
        if flags & RenderFlags.SHADOWS_SPOT and not shadow_fraction:  # else the colour pass drew them
            with timed(timings, "shadow", GL.glFinish):
                opaque = _posed_primitives(scene, [n for n in scene.mesh_nodes if n in casters and n not in filters])
                corners = self._caster_corners(opaque)
                for node in scene.mesh_nodes:
                    node.mesh.is_visible = node in casters and node not in filters
                for light_node in scene.light_nodes & (shadowed if stale is None else stale):
                    self._shadow_writes = self._caster_texels(scene, light_node, flags, corners, self.shadow_map_size)
                    if opaque:
                        self._shadow_mapping_pass(scene, light_node, flags)
                    else:  # only clear the map (pyrender's pass fails with nothing to draw)
                        self._configure_shadow_mapping_viewport(light_node.light, flags)
                if self._filtered:
                    # Tile k is read by the shader's k-th spot light: pyrender's binding order.
                    spots = [n for n in ranked(scene.light_nodes) if isinstance(n.light, pyrender.SpotLight)]
                    tiles = [(k, n) for k, n in enumerate(spots) if n in shadowed]
                    self.transmittance.reserve(tiles[-1][0] + 1)
                    tinted = _posed_primitives(scene, filters)
                    tinted_corners = self._caster_corners(tinted)
                    for k, light_node in tiles:
                        self._transmittance_pass(scene, light_node, k, tinted, tinted_corners, flags)
        self._n_shadowed = len(shadowed)
        self._program_cache.transmittance = self._filtered
        self._program_cache.shadow_fraction = shadow_fraction
        self._program_cache.shadow_free = shadow_free
        self._outputs = 2 if shadow_free else 1
        split = painting_parts is not None and bool(painting_parts[1]) and bool(flags & RenderFlags.SHADOWS_SPOT)
        self._split = (painting_parts[0].mesh.primitives[0], painting_parts[1], scene) if split else None
        self._painting_primitive = painting_parts[0].mesh.primitives[0] if painting_parts is not None else None
        groups = light_group_count(scene) if painting_parts is not None else None  # only the painting's program uses it
        self._light_groups = groups if groups is not None and groups <= self.unrolled_light_groups else None
        self._stencil = stencil
        with timed(timings, step, GL.glFinish):
            for node in scene.mesh_nodes:
                node.mesh.is_visible = node in seen
            try:
                self._forward_pass(scene, flags, seg_node_map=seg_node_map)
            finally:
                if self._stencil:
                    GL.glDisable(GL.GL_STENCIL_TEST)
                self._split = self._painting_primitive = self._light_groups = None
                self._program_cache.shadow_fraction = self._program_cache.shadow_free = False
                self._outputs = 1
                self._stencil = False
        with timed(timings, "readback"):
            images = self._target.end_drawing()
        return images if shadow_free else images[0]
