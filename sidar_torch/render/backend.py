"""Every override of pyrender in one place: what the renderer changes in pyrender, and why.

* :class:`GLRenderer` (a ``pyrender.Renderer``): a long-lived context drawing many small scenes
  into its own framebuffer, with pooled uploads, every spot light shading, any power-of-two shadow
  map, fitted shadow frusta, transmittance maps for transparent casters, and no GL call at
  garbage collection (its docstring lists each change);
* :class:`ProgramCache` and its programs: the program cache fix (pyrender's never hits on OSMesa),
  linking without PyOpenGL's validation, and pyrender's shaders patched as ``shader_patches``
  says (quirks 1-7 there);
* :class:`RankedNode`: scene nodes hashed by insertion rank, so lights are summed in a fixed order.

Nothing else in the package subclasses or patches pyrender.
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np
import pyrender
from OpenGL import GL
from OpenGL.GL import shaders as gl_shaders
from pyrender.constants import MAX_N_LIGHTS, RenderFlags
from pyrender.shader_program import ShaderProgram, ShaderProgramCache

from ..render_choices import MAX_SHADOWED_LIGHTS
from ..timing import timed
from .framebuffer import FLIP_Y, Framebuffer
from .mirror import MIRROR_DEFINES, REFRACTION, PaintingMirror
from .shader_patches import SHADER_SOURCES, glsl, patch_source
from .transmittance import TransmittanceMaps, vertex_defines

__all__ = ["GLRenderer", "ProgramCache", "RankedNode", "add_node", "frustum_projection", "transmits"]

SHADOW_SAMPLER = pyrender.Sampler(
    magFilter=GL.GL_LINEAR, minFilter=GL.GL_LINEAR, wrapS=GL.GL_CLAMP_TO_EDGE, wrapT=GL.GL_CLAMP_TO_EDGE,
)
"""Linear filtering of a depth-compare texture is the hardware's 2 x 2 percentage-closer filter."""


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


def transmits(node: pyrender.Node) -> bool:
    """Whether a mesh node is blended (transparent): it casts a tinted shadow, not a dark one."""
    return any(p.material.alphaMode == "BLEND" for p in node.mesh.primitives)


class RankedNode(pyrender.Node):
    """A scene node whose hash is its insertion rank in the scene, not its memory address.

    pyrender keeps nodes in sets and sums the lights in set order; address-based hashes make
    that order, and so the float rounding of the sum, change from one render to the next.
    """

    def __init__(self, rank: int, **kwargs: Any):
        super().__init__(**kwargs)
        self._rank = rank

    def __hash__(self) -> int:
        return self._rank


def add_node(scene: pyrender.Scene, pose: np.ndarray | None = None, **obj: Any) -> pyrender.Node:
    """Add ``mesh=``, ``light=`` or ``camera=`` to ``scene`` at ``pose`` as a :class:`RankedNode`."""
    node = RankedNode(len(scene.nodes), matrix=pose, **obj)
    scene.add_node(node)
    return node


class _PatchedProgram(ShaderProgram):
    """A pyrender shader program built from patched sources and linked without validation."""

    def _load(self, shader_filename: str) -> str:
        name = os.path.basename(shader_filename)
        if name in SHADER_SOURCES:
            return glsl(name)
        return patch_source(name, super()._load(shader_filename), self.defines)

    def _add_to_context(self) -> None:
        if self._program_id is not None:
            raise ValueError("Shader program already in context")
        stages = [(self.vertex_shader, GL.GL_VERTEX_SHADER), (self.fragment_shader, GL.GL_FRAGMENT_SHADER),
                  (self.geometry_shader, GL.GL_GEOMETRY_SHADER)]
        shader_ids = [gl_shaders.compileShader(self._load(path), kind) for path, kind in stages if path]
        self._vao_id = GL.glGenVertexArrays(1)
        GL.glBindVertexArray(self._vao_id)  # a VAO must be bound while linking (PyOpenGL)
        self._program_id = gl_shaders.compileProgram(*shader_ids, validate=False)
        GL.glBindVertexArray(0)


class ProgramCache(ShaderProgramCache):
    """pyrender's program cache for a single GL context: keyed by shader files and defines only.

    ``len(cache)`` is the number of distinct programs built, which stays constant over a long run.

    While :attr:`transmittance` is true, lit programs with spot-light shadows are the variant
    that also reads the transmittance maps (define ``TRANSMITTANCE_SHADOWS``, quirk 7). While
    :attr:`mirror` names a define of ``mirror.MIRROR_DEFINES``, lit programs are that variant
    (the painting reflected or refracted, quirk 8; set per primitive by ``GLRenderer``).

    Args:
        shadow_taps: 4 (3 x 3 tent filter) or 1 (2 x 2 filter) depth-compare taps per shadow lookup.
    """

    def __init__(self, shadow_taps: int = 4):
        super().__init__()
        self._extra_defines = {"SIDAR_SHADOW_TAPS": shadow_taps}
        self.transmittance = False
        self.mirror: str | None = None

    def get_program(self, vertex_shader, fragment_shader, geometry_shader=None, defines=None):
        defines = {**(defines or {}), **self._extra_defines}
        if self.transmittance and fragment_shader == "mesh.frag" and "SPOT_LIGHT_SHADOWS" in defines:
            defines["TRANSMITTANCE_SHADOWS"] = 1
        if self.mirror and fragment_shader == "mesh.frag":
            defines[self.mirror] = 1
        names = tuple(os.path.basename(s) for s in (vertex_shader, fragment_shader, geometry_shader) if s)
        key = names + tuple(sorted(defines.items()))
        if key not in self._program_cache:
            paths = [os.path.join(self.shader_dir, s) if s else None
                     for s in (vertex_shader, fragment_shader, geometry_shader)]
            self._program_cache[key] = _PatchedProgram(*paths, defines=defines)
        return self._program_cache[key]

    def __len__(self) -> int:
        return len(self._program_cache)


class GLRenderer(pyrender.Renderer):
    """pyrender's renderer, adapted to a long-lived context that draws many small scenes.

    * programs come from :class:`ProgramCache` (stable key, patched shaders);
    * :meth:`_update_context` uploads what is new and frees only textures no longer used (the
      previous painting, once a draw uses another); pooled meshes and shadow maps stay uploaded
      until :meth:`delete`;
    * every spot light can shade, with or without shadows (pyrender limits unshadowed lights
      to the 4 nearest);
    * shadow maps may be any power-of-two size, drawn with the fitted frusta of :attr:`shadow_frusta`;
    * forward passes draw upside down into its own single-sampled :class:`Framebuffer` (EGL
      contexts have no default framebuffer; ``framebuffer`` explains the orientation);
    * transparent casters tint and lighten their shadows through transmittance maps instead of
      darkening the depth maps (``render.transmittance``);
    * reflective and glass occluders are drawn with the program variant of their material's
      ``mirror`` define, with the painting of :attr:`painting` bound (``render.mirror``);
    * garbage collection issues no GL call (pyrender's ``__del__`` deletes its objects by id in
      whatever context is current, which may be another renderer's): the objects die with
      their context, which :class:`~.renderer.SceneRenderer` destroys.
    """

    def __init__(self, width: int, height: int, shadow_map_size: int, shadow_taps: int):
        super().__init__(width, height)
        self._program_cache = ProgramCache(shadow_taps)
        self._target = Framebuffer(width, height)
        self.shadow_map_size = shadow_map_size
        self._unused_shadow_map = self.new_shadow_map()
        self._unused_shadow_map._add_to_context()
        self._make_depth_compare(self._unused_shadow_map)
        self._n_shadowed = 0  # shadow-casting spot lights of the current draw (see draw)
        self.shadow_frusta: dict[pyrender.Node, np.ndarray] = {}
        """Light node -> fitted frustum (``visibility.light_frustum``) for the next draws; a light
        not in it gets pyrender's frustum, fitted to its cone."""
        self.transmittance = TransmittanceMaps(shadow_map_size // 2)
        self._filtered = False  # whether the current draw's lights have transmittance maps
        self.painting: PaintingMirror | None = None
        """The painting that reflective and glass occluders show in the next lit draws."""
        self._mirror_sampler = GL.glGenSamplers(1)  # trilinear whatever the painting's own filter
        for name, value in ((GL.GL_TEXTURE_MIN_FILTER, GL.GL_LINEAR_MIPMAP_LINEAR), (GL.GL_TEXTURE_MAG_FILTER, GL.GL_LINEAR),
                            (GL.GL_TEXTURE_WRAP_S, GL.GL_CLAMP_TO_EDGE), (GL.GL_TEXTURE_WRAP_T, GL.GL_CLAMP_TO_EDGE)):
            GL.glSamplerParameteri(self._mirror_sampler, name, value)
        self._mirror_unit: int | None = None  # texture unit the sampler is bound to during a draw

    def new_shadow_map(self) -> pyrender.Texture:
        """A depth texture for one light's shadow map (uploaded at first use)."""
        return pyrender.Texture(width=self.shadow_map_size, height=self.shadow_map_size, source_channels="D",
                                data_format=GL.GL_FLOAT, sampler=SHADOW_SAMPLER)

    @staticmethod
    def _make_depth_compare(texture: pyrender.Texture) -> None:
        """Turn an uploaded depth texture into a depth-compare sampler (the patched shader reads it
        with hardware filtering)."""
        texture._bind()
        GL.glTexParameteri(GL.GL_TEXTURE_2D, GL.GL_TEXTURE_COMPARE_MODE, GL.GL_COMPARE_REF_TO_TEXTURE)
        GL.glTexParameteri(GL.GL_TEXTURE_2D, GL.GL_TEXTURE_COMPARE_FUNC, GL.GL_LEQUAL)
        texture._unbind()

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
        for light in scene.lights:
            if light.shadow_texture not in self._shadow_textures:
                light.shadow_texture._add_to_context()
                self._make_depth_compare(light.shadow_texture)
                self._shadow_textures.add(light.shadow_texture)

    def __del__(self) -> None:
        pass

    def _bind_lighting(self, scene, program, node, flags) -> None:
        """pyrender's light binding, then the unused shadow samplers bound to one spare map and
        the transmittance maps bound after them.

        llvmpipe compiles a fragment-shader variant for every distinct layout of bound textures
        (about 1 s each). pyrender binds only the lights present, on units 0..k-1, and the
        painting on unit k, so every light count was a new layout. With all shadow samplers
        and the transmittance maps bound (used or not), the layout is the same for every lit draw.
        """
        super()._bind_lighting(scene, program, node, flags)
        shadowed = bool(flags & RenderFlags.SHADOWS_SPOT)
        program.set_uniform("n_shadowed_spot_lights", self._n_shadowed if shadowed else 0)
        if shadowed:
            for i in range(len(scene.spot_light_nodes), MAX_SHADOWED_LIGHTS):
                self._bind_texture(self._unused_shadow_map, f"spot_lights[{i}].shadow_map", program)
            if self._filtered:  # the transmittance variant (same layout in every draw that uses it)
                self._bind_texture(self.transmittance, "transmittance_maps", program)
                program.set_uniform("transmittance_layout", np.array(self.transmittance.layout, np.int32))

    def _get_primitive_program(self, primitive, flags, program_flags):
        """pyrender's program choice; a lit occluder with a ``mirror`` material gets that variant."""
        self._program_cache.mirror = getattr(primitive.material, "mirror", None) if self.painting else None
        try:
            return super()._get_primitive_program(primitive, flags, program_flags)
        finally:
            self._program_cache.mirror = None

    def _bind_and_draw_primitive(self, primitive, pose, program, flags) -> None:
        """pyrender's draw; in a quirk-8 variant, the painting is bound first (its texture on the next
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
        super()._bind_and_draw_primitive(primitive, pose, program, flags)

    def _reset_active_textures(self) -> None:
        """pyrender's reset after each primitive, and the painting's sampler unbound (the unit goes
        to the next primitive's textures, which keep their own filters)."""
        if self._mirror_unit is not None:
            GL.glBindSampler(self._mirror_unit, 0)
            self._mirror_unit = None
        super()._reset_active_textures()

    def _compute_max_n_lights(self, flags: int) -> list[int]:
        return [MAX_N_LIGHTS, MAX_SHADOWED_LIGHTS, MAX_N_LIGHTS]

    def _configure_forward_pass_viewport(self, flags) -> None:
        """pyrender's forward-pass state (it binds framebuffer 0 for drawing), then our framebuffer."""
        super()._configure_forward_pass_viewport(flags)
        self._target.begin_drawing()

    def _get_camera_matrices(self, scene: pyrender.Scene) -> tuple[np.ndarray, np.ndarray]:
        """pyrender's view and projection matrices, the projection flipped to draw upside down."""
        V, P = super()._get_camera_matrices(scene)
        return V, FLIP_Y @ P

    def _get_light_cam_matrices(self, scene, light_node, flags) -> tuple[np.ndarray, np.ndarray]:
        """The light's view and projection: pyrender's (a square frustum 2 outer cone + pi / 16
        wide, depths from 1 % to 10x the scene's size), or the fitted :attr:`shadow_frusta` one.

        The shadow pass and the lit shader's lookup both take the matrices from here, so the map
        is always read with the projection it was drawn with.
        """
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

    def _configure_shadow_mapping_viewport(self, light, flags) -> None:
        super()._configure_shadow_mapping_viewport(light, flags)
        GL.glViewport(0, 0, self.shadow_map_size, self.shadow_map_size)

    def _transmittance_pass(self, scene: pyrender.Scene, light_node: pyrender.Node, k: int,
                            filters: list[pyrender.Node], flags: int) -> None:
        """Draw the transparent casters ``filters`` into tile ``k`` of the transmittance maps, from
        ``light_node`` with the light matrix of its depth map."""
        V, P = self._get_light_cam_matrices(scene, light_node, flags)
        casters = [(p, scene.get_pose(node)) for node in filters for p in node.mesh.primitives]
        self.transmittance.draw_tile(k, V, P, scene.get_pose(light_node)[:3, 3], casters,
                                     self._transmittance_program)

    def _transmittance_program(self, primitive: pyrender.Primitive):
        program = self._program_cache.get_program("mesh.vert", "transmittance.frag",
                                                  defines=vertex_defines(primitive))
        if not program._in_context():
            program._add_to_context()
        return program

    def draw(self, scene: pyrender.Scene, flags: int, seen: set, casters: set = frozenset(),
             shadowed: set = frozenset(), seg_node_map: dict | None = None,
             timings: dict[str, float] | None = None, step: str = "colour", stale: set | None = None) -> np.ndarray:
        """Draw ``scene`` into the renderer's framebuffer and read it back as ``(H, W, 4)`` uint8.

        Args:
            flags: pyrender render flags; with ``SHADOWS_SPOT`` every light gets a shadow map.
            seen: mesh nodes the camera sees.
            casters: mesh nodes that cast shadows: opaque ones go into the depth maps, blended
                (transparent) ones into the transmittance maps, which are drawn and looked up
                only when there is one.
            shadowed: light nodes that get a shadow map and lookup (with ``SHADOWS_SPOT``); they
                must be the first spot lights in the scene's order.
            seg_node_map: node -> grey level, for ``RenderFlags.SEG`` draws.
            timings: if given, seconds are added to ``"upload"`` (new textures and meshes),
                ``"shadow"`` (shadow-map passes), ``step`` (the forward pass) and ``"readback"``.
            step: the name the forward pass is timed under (``"colour"``, ``"mask"``, ``"opacity"``,
                ``"label"``).
            stale: the nodes of ``shadowed`` whose shadow maps are drawn (default: all); the
                others' maps must already hold what this scene would draw into them.

        Where GL time lands: pyrender ends every pass with ``glFlush``, and llvmpipe with
        ``LP_NUM_THREADS=0`` rasterises the queued draws in this thread before a flush returns,
        so a pass's time is its own. When timing, each step also ends with ``glFinish`` (a no-op
        here, but it keeps asynchronous drivers, e.g. a GPU under EGL, from billing the draws
        to ``readback``); it does not change a pixel.
        """
        with timed(timings, "upload", GL.glFinish):
            self._update_context(scene, flags)
        filters = sorted((n for n in casters if transmits(n)), key=hash)  # hash: rank in the scene
        self._filtered = bool(filters) and bool(flags & RenderFlags.SHADOWS_SPOT)
        if flags & RenderFlags.SHADOWS_SPOT:
            with timed(timings, "shadow", GL.glFinish):
                opaque = False
                for node in scene.mesh_nodes:
                    node.mesh.is_visible = node in casters and node not in filters
                    opaque |= node.mesh.is_visible
                for light_node in scene.light_nodes & (shadowed if stale is None else stale):
                    if opaque:
                        self._shadow_mapping_pass(scene, light_node, flags)
                    else:  # only clear the map (pyrender's pass fails with nothing to draw)
                        self._configure_shadow_mapping_viewport(light_node.light, flags)
                if self._filtered:
                    # Tile k is read by the shader's k-th spot light: pyrender's binding order.
                    spots = [n for n in scene.light_nodes if isinstance(n.light, pyrender.SpotLight)]
                    tiles = [(k, n) for k, n in enumerate(spots) if n in shadowed]
                    self.transmittance.reserve(tiles[-1][0] + 1)
                    for k, light_node in tiles:
                        self._transmittance_pass(scene, light_node, k, filters, flags)
        self._n_shadowed = len(shadowed)
        self._program_cache.transmittance = self._filtered
        with timed(timings, step, GL.glFinish):
            for node in scene.mesh_nodes:
                node.mesh.is_visible = node in seen
            self._forward_pass(scene, flags, seg_node_map=seg_node_map)
        with timed(timings, "readback"):
            return self._target.end_drawing()
