"""The backend: a :class:`~sidar_torch.scene.SceneSequence` and a painting in, pixels out.

:class:`SceneRenderer` owns one offscreen GL context and everything uploaded to it (shader
programs, meshes, shadow maps, the current painting's texture) and reuses them for every
sample. Create it in the process that uses it (a DataLoader worker creates its own).

Per view it draws, in the camera's pixel grid (Kornia convention, see ``geometry``):

* the **view**: the painting under the view's ambient level and lights, with occluders and
  shadows; 8-bit sRGB (the shader's output encoding is exact sRGB, see ``programs``);
* the **mask**: a segmentation draw of the painting (white) and the camera-visible occluders
  (black) with depth testing, so occluder parts behind the painting never count; background
  and occluders are 1. Occluders less opaque than ``sequence.mask_min_opacity`` are left out
  of this draw, so the painting seen through them counts as visible.

and once per sequence the **label**: the painting through view 0's camera, unlit and without
occluders (the texture as the reference camera samples it).

``SceneRenderer.render(..., timings=dict)`` adds the seconds spent in each step to the dict
(``upload``, ``graph``, ``shadow``, ``colour``, ``mask``, ``label``, ``readback``; see
:meth:`_GLRenderer.draw` for how GL time is attributed).

Lights are spot lights (``scene`` explains how point and area lights map to them). The
painting is left out of shadow maps: a plane lit from its front cannot shadow itself, and
occluder parts behind it are farther from the light than the plane, so they cannot darken it
either. This removes shadow acne on the painting altogether.
"""

from __future__ import annotations

import os
import weakref
from dataclasses import dataclass
from typing import Any

import numpy as np
import pyrender
from OpenGL import GL
from pyrender.constants import MAX_N_LIGHTS, RenderFlags

from ..config import MAX_SHADOWED_LIGHTS
from ..geometry import ball_may_be_seen, clip_polygon, look_at, plane_corners, shadow_may_reach, visible_halfplanes
from ..scene import CAMERA_CLEARANCE, Camera, Light, Material, SceneSequence, ViewScene
from ..timing import timed
from .context import open_context
from .meshes import MeshPool, plane_mesh
from .programs import ProgramCache, surface_factors
from .transmittance import TransmittanceMaps, vertex_defines

__all__ = ["RenderedSequence", "SceneRenderer", "shared_renderer"]

GL_FROM_CV = np.diag([1.0, -1.0, -1.0, 1.0])
"""Converts camera axes between the OpenCV frame (y down, z forward) and OpenGL's (y up, z back)."""

PAINTING_SAMPLER = pyrender.Sampler(
    magFilter=GL.GL_LINEAR, minFilter=GL.GL_LINEAR_MIPMAP_LINEAR,
    wrapS=GL.GL_CLAMP_TO_EDGE, wrapT=GL.GL_CLAMP_TO_EDGE,
)
"""Trilinear filtering; clamping keeps texels of the opposite edge out of the border pixels."""

SHADOW_SAMPLER = pyrender.Sampler(
    magFilter=GL.GL_LINEAR, minFilter=GL.GL_LINEAR, wrapS=GL.GL_CLAMP_TO_EDGE, wrapT=GL.GL_CLAMP_TO_EDGE,
)
"""Linear filtering of a depth-compare texture is the hardware's 2 x 2 percentage-closer filter."""


@dataclass(frozen=True)
class RenderedSequence:
    """The pixels of one sequence.

    Attributes:
        views: ``(V, H, W, 3)`` uint8 sRGB.
        masks: ``(V, H, W)`` bool, True where the painting is not visible.
        label: ``(H, W, 3)`` uint8 sRGB, the painting as view 0's camera sees it, unlit.
    """

    views: np.ndarray
    masks: np.ndarray
    label: np.ndarray


def gl_camera(camera: Camera, znear: float, zfar: float) -> tuple[pyrender.IntrinsicsCamera, np.ndarray]:
    """pyrender camera and its camera-to-world pose (OpenGL frame) for a Kornia-convention camera.

    The one place where pixel conventions meet: OpenGL puts pixel centres at +0.5 in window
    coordinates, Kornia at integers, so the principal point shifts by half a pixel (``cy``
    counts from the top row in both).
    """
    K = camera.K
    gl = pyrender.IntrinsicsCamera(fx=K[0, 0], fy=K[1, 1], cx=K[0, 2] + 0.5, cy=K[1, 2] + 0.5,
                                   znear=znear, zfar=zfar)
    return gl, _gl_pose(camera.R, camera.t)


def _gl_pose(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """pyrender node pose (camera-to-world, OpenGL axes: looks along -z) of the OpenCV-frame
    world-to-camera pose ``R, t``. Cameras and lights (which shine along -z) both use it."""
    world_from_cv = np.eye(4)
    world_from_cv[:3, :3] = R.T
    world_from_cv[:3, 3] = -R.T @ t
    return world_from_cv @ GL_FROM_CV


def _clip_range(camera: Camera, image_size: tuple[int, int]) -> tuple[float, float]:
    """Near and far clip distances (painting units, along the optical axis).

    Far lies beyond the painting's farthest corner. Near is far / 2000 (24-bit depth then resolves
    about 1e-4 painting units at the painting), or less for a camera closer to the painting than
    that: every painting point is at least the camera's height ``z`` away, and every occluder at
    least :data:`~sidar_torch.scene.CAMERA_CLEARANCE`; a point at distance ``r`` inside the view
    is at depth at least ``r cos(theta)``, ``theta`` the angle of the image's farthest corner
    from the axis. Near is half the smaller such depth.
    """
    zfar = 2.0 * float(np.linalg.norm(plane_corners(image_size) - camera.position, axis=1).max())
    h, w = image_size
    f = camera.K[0, 0]
    corner = np.hypot(max(camera.K[0, 2] + 0.5, w - 0.5 - camera.K[0, 2]), max(camera.K[1, 2] + 0.5, h - 0.5 - camera.K[1, 2]))
    cos_corner = f / np.hypot(f, corner)
    nearest = min(float(camera.position[2]), CAMERA_CLEARANCE) * cos_corner
    return min(zfar / 2000.0, nearest / 2), zfar


def _gl_material(material: Material, texture: pyrender.Texture | None = None) -> pyrender.MetallicRoughnessMaterial:
    return pyrender.MetallicRoughnessMaterial(
        baseColorFactor=material.base_color.astype(np.float64),  # floats: ints would be read as 0-255
        metallicFactor=float(material.metallic),
        roughnessFactor=float(material.roughness),
        emissiveFactor=surface_factors(material.specular, material.coat, material.coat_roughness),
        alphaMode="BLEND" if material.transparent else "OPAQUE",
        baseColorTexture=texture,
    )


def _transmits(node: pyrender.Node) -> bool:
    """Whether a mesh node is blended (transparent): it casts a tinted shadow, not a dark one."""
    return any(p.material.alphaMode == "BLEND" for p in node.mesh.primitives)


class _RankedNode(pyrender.Node):
    """A scene node whose hash is its insertion rank in the scene, not its memory address.

    pyrender keeps nodes in sets and sums the lights in set order; address-based hashes make
    that order, and so the float rounding of the sum, change from one render to the next.
    """

    def __init__(self, rank: int, **kwargs: Any):
        super().__init__(**kwargs)
        self._rank = rank

    def __hash__(self) -> int:
        return self._rank


def _add(scene: pyrender.Scene, pose: np.ndarray | None = None, **obj: Any) -> pyrender.Node:
    """Add ``mesh=``, ``light=`` or ``camera=`` to ``scene`` at ``pose`` as a :class:`_RankedNode`."""
    node = _RankedNode(len(scene.nodes), matrix=pose, **obj)
    scene.add_node(node)
    return node


class _GLRenderer(pyrender.Renderer):
    """pyrender's renderer, adapted to a long-lived context that draws many small scenes.

    * programs come from :class:`ProgramCache` (stable key, patched shaders);
    * :meth:`_update_context` uploads what is new and frees only textures no longer used (the
      previous painting); pooled meshes and shadow maps stay uploaded until :meth:`delete`;
    * every spot light can shade, with or without shadows (pyrender limits unshadowed lights
      to the 4 nearest);
    * shadow maps may be any power-of-two size;
    * transparent casters tint and lighten their shadows through transmittance maps instead of
      darkening the depth maps (``render.transmittance``);
    * garbage collection issues no GL call (pyrender's ``__del__`` deletes its objects by id in
      whatever context is current, which may be another renderer's): the objects die with
      their context, which :class:`SceneRenderer` destroys.
    """

    def __init__(self, width: int, height: int, shadow_map_size: int):
        super().__init__(width, height)
        self._program_cache = ProgramCache()
        self.shadow_map_size = shadow_map_size
        self._unused_shadow_map = self.new_shadow_map()
        self._unused_shadow_map._add_to_context()
        self._make_depth_compare(self._unused_shadow_map)
        self._n_shadowed = 0  # shadow-casting spot lights of the current draw (see draw)
        self.transmittance = TransmittanceMaps(shadow_map_size // 2)
        self._filtered = False  # whether the current draw's lights have transmittance maps

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
        if flags & RenderFlags.SHADOWS_SPOT:
            program.set_uniform("n_shadowed_spot_lights", self._n_shadowed)
            for i in range(len(scene.spot_light_nodes), MAX_SHADOWED_LIGHTS):
                self._bind_texture(self._unused_shadow_map, f"spot_lights[{i}].shadow_map", program)
            if self._filtered:  # the transmittance variant (same layout in every draw that uses it)
                self._bind_texture(self.transmittance, "transmittance_maps", program)
                program.set_uniform("transmittance_layout", np.array(self.transmittance.layout, np.int32))

    def _compute_max_n_lights(self, flags: int) -> list[int]:
        return [MAX_N_LIGHTS, MAX_SHADOWED_LIGHTS, MAX_N_LIGHTS]

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
             timings: dict[str, float] | None = None, step: str = "colour") -> np.ndarray:
        """Draw ``scene`` into the context's buffer and read it back as ``(H, W, 4)`` uint8.

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
            step: the name the forward pass is timed under (``"colour"``, ``"mask"``, ``"label"``).

        Where GL time lands: pyrender ends every pass with ``glFlush``, and llvmpipe with
        ``LP_NUM_THREADS=0`` rasterises the queued draws in this thread before a flush returns,
        so a pass's time is its own. When timing, each step also ends with ``glFinish`` (a no-op
        here, but it keeps asynchronous drivers, e.g. a GPU under EGL, from billing the draws
        to ``readback``); it does not change a pixel.
        """
        with timed(timings, "upload", GL.glFinish):
            self._update_context(scene, flags)
        filters = sorted((n for n in casters if _transmits(n)), key=hash)  # hash: rank in the scene
        self._filtered = bool(filters) and bool(flags & RenderFlags.SHADOWS_SPOT)
        if flags & RenderFlags.SHADOWS_SPOT:
            with timed(timings, "shadow", GL.glFinish):
                opaque = False
                for node in scene.mesh_nodes:
                    node.mesh.is_visible = node in casters and node not in filters
                    opaque |= node.mesh.is_visible
                for light_node in scene.light_nodes & shadowed:
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
            GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, 0)  # shadow passes leave their framebuffer bound
            GL.glReadBuffer(GL.GL_FRONT)
            GL.glPixelStorei(GL.GL_PACK_ALIGNMENT, 1)
            pixels = GL.glReadPixels(0, 0, self.viewport_width, self.viewport_height, GL.GL_RGBA,
                                     GL.GL_UNSIGNED_BYTE)
            image = np.frombuffer(pixels, dtype=np.uint8).reshape(self.viewport_height, self.viewport_width, 4)
            return np.ascontiguousarray(image[::-1])  # OpenGL's first row is the bottom one


class SceneRenderer:
    """Renders scene sequences of one output size in one offscreen GL context.

    Args:
        image_size: ``(H, W)`` of every view, in pixels.
        shadow_map_size: side of each shadow map, texels (power of two).
    """

    def __init__(self, image_size: tuple[int, int], shadow_map_size: int = 1024, skip_idle_shadows: bool = True):
        self.image_size = tuple(image_size)
        self.skip_idle_shadows = skip_idle_shadows
        h, w = self.image_size
        self._platform = open_context(w, h)
        # Destroying the context frees every GL object in it; it needs no current context, so a
        # collected renderer cannot disturb another one mid-render. Runs at exit too.
        self._release = weakref.finalize(self, self._platform.delete_context)
        self._gl = _GLRenderer(w, h, shadow_map_size)
        GL.glPixelStorei(GL.GL_UNPACK_ALIGNMENT, 1)
        self._meshes = MeshPool()
        self._plane = plane_mesh(self.image_size)
        self._lights: list[pyrender.SpotLight] = []
        self._painting: np.ndarray | None = None
        self._texture: pyrender.Texture | None = None

    @property
    def program_count(self) -> int:
        """Number of shader programs built so far (constant once every variant has been used)."""
        return len(self._gl._program_cache)

    @property
    def shadow_map_count(self) -> int:
        """Number of pooled spot lights, each with its own ``shadow_map_size``-square float32
        shadow map: grows to the most emitters one view has used, then stays."""
        return len(self._lights)

    def render(self, sequence: SceneSequence, painting: np.ndarray,
               timings: dict[str, float] | None = None) -> RenderedSequence:
        """Render every view, mask and the label of ``sequence`` with ``painting`` as texture.

        Args:
            sequence: the scenes; its ``image_size`` must be this renderer's.
            painting: ``(H, W, 3)`` uint8 sRGB, the texture (one texel per reference-view pixel).
            timings: if given, seconds spent are added to its keys ``"upload"`` (painting
                texture and meshes), ``"graph"`` (building pyrender scenes), ``"shadow"``,
                ``"colour"``, ``"mask"`` and ``"label"`` (draw passes) and ``"readback"``; the
                pixels are the same either way.
        """
        if tuple(sequence.image_size) != self.image_size:
            raise ValueError(f"sequence.image_size {sequence.image_size} != renderer image_size {self.image_size}")
        if painting.shape != (*self.image_size, 3) or painting.dtype != np.uint8:
            raise ValueError(f"painting: expected {(*self.image_size, 3)} uint8, got {painting.shape} {painting.dtype}")
        if not self._release.alive:
            raise RuntimeError("SceneRenderer.render called after close()")
        self._platform.make_current()
        with timed(timings, "upload"):  # the texture object; its GL upload is timed in draw
            texture = self._painting_texture(painting)
        views, masks = [], []
        for view in sequence.views:
            image, mask = self._render_view(view, sequence, texture, timings)
            views.append(image)
            masks.append(mask)
        label = self._render_label(sequence.views[0].camera, texture, timings)
        return RenderedSequence(np.stack(views), np.stack(masks), label)

    def close(self) -> None:
        """Destroy the context and every GL object in it (safe to call twice)."""
        self._release()

    def disown(self) -> None:
        """Retire this renderer without touching its context: for a forked child holding a copy of
        its parent's renderer, whose GL state it must neither use nor free.

        The renderer is kept alive for the rest of the process: the inherited context may still
        be current, and freeing its pixel buffer (or letting pyrender's ``Platform.__del__``
        destroy it) would hand Mesa freed or foreign state.
        """
        self._release.detach()
        _DISOWNED.append(self)

    def _painting_texture(self, painting: np.ndarray) -> pyrender.Texture:
        """The painting's texture, created (and uploaded at first draw) once per painting."""
        if self._texture is None or not np.array_equal(painting, self._painting):
            rgba = np.concatenate([painting, np.full((*painting.shape[:2], 1), 255, np.uint8)], axis=2)
            self._texture = pyrender.Texture(source=rgba, source_channels="RGBA", sampler=PAINTING_SAMPLER)
            self._painting = painting.copy()
        return self._texture

    def _new_scene(self, camera: Camera, ambient: float, texture: pyrender.Texture, material: Material):
        scene = pyrender.Scene(bg_color=(0.0, 0.0, 0.0, 1.0), ambient_light=np.full(3, ambient))
        self._plane.primitives[0].material = _gl_material(material, texture)
        plane = _add(scene, mesh=self._plane)
        gl_cam, pose = gl_camera(camera, *_clip_range(camera, self.image_size))
        _add(scene, pose, camera=gl_cam)
        return scene, plane

    def _render_view(self, view: ViewScene, sequence: SceneSequence, texture: pyrender.Texture,
                     timings: dict[str, float] | None = None):
        with timed(timings, "graph"):
            scene, plane = self._new_scene(view.camera, view.ambient, texture, view.plane_material)
            occluders, opaque_enough = set(), set()
            counts: dict[tuple[str, int], int] = {}
            for occ in view.occluders:
                key = (occ.shape, occ.variant)
                mesh = self._meshes.take(*key, counts.setdefault(key, 0))
                counts[key] += 1
                mesh.primitives[0].material = _gl_material(occ.material)
                node = _add(scene, occ.object_to_world(), mesh=mesh)
                occluders.add(node)
                if occ.material.base_color[3] >= sequence.mask_min_opacity:
                    opaque_enough.add(node)
            order, n_shadowed = self._casting_emitters(view, sequence.occluders_visible)
            shadowed = self._add_lights(scene, view.lights, order, n_shadowed if sequence.shadows else 0)
        visible = occluders if sequence.occluders_visible else set()
        # With no emitter that can cast a shadow on what the camera sees (the painting is not a
        # caster), the unshadowed draw gives the same pixels without the shadow passes.
        flags = RenderFlags.SHADOWS_SPOT if shadowed else RenderFlags.NONE
        image = self._gl.draw(scene, flags, seen={plane} | visible, casters=occluders, shadowed=shadowed,
                              timings=timings, step="colour")
        masked = visible & opaque_enough
        seg_map = {plane: 255, **{node: 0 for node in masked}}
        seg = self._gl.draw(scene, RenderFlags.SEG, seen={plane} | masked, seg_node_map=seg_map,
                            timings=timings, step="mask")
        return image[..., :3], seg[..., 0] < 128

    def _casting_emitters(self, view: ViewScene, occluders_visible: bool = True) -> tuple[list[tuple[int, int]], int]:
        """Every emitter as ``(light, emitter)`` indices, those that may shadow something the camera
        sees first, and how many those are (all when :attr:`skip_idle_shadows` is false).

        Safe to skip an emitter's shadow pass and lookup (its lookup would return "lit" at every
        pixel) when no visible occluder is in view (occluders shadow themselves and each other) and no
        occluder's shadow from it can fall on the part of the painting the camera sees (see
        :func:`sidar_torch.geometry.shadow_may_reach`). Both tests are conservative.
        """
        cam = view.camera
        emitters = [(a, b) for a, light in enumerate(view.lights) for b in range(len(light.emitters))]
        balls = [(occ.position, float(np.linalg.norm(occ.scale))) for occ in view.occluders]
        if not balls:
            return emitters, 0
        if occluders_visible and any(ball_may_be_seen(cam.K, cam.R, cam.t, self.image_size, c, r) for c, r in balls):
            return emitters, len(emitters)
        region = clip_polygon(plane_corners(self.image_size)[:, :2],
                              visible_halfplanes(cam.K, cam.R, cam.t, self.image_size))
        casting = {(a, b) for a, b in emitters
                   if any(shadow_may_reach(view.lights[a].emitters[b], c, r, region) for c, r in balls)}
        # The same order either way, so skipping changes no rounding of the shader's sum.
        order = sorted(emitters, key=lambda ab: ab not in casting)
        return order, len(casting) if self.skip_idle_shadows else len(order)

    def _add_lights(self, scene: pyrender.Scene, lights: tuple[Light, ...], order: list[tuple[int, int]],
                    n_shadowed: int) -> set[pyrender.Node]:
        """Add the emitters ``order`` (``(light, emitter)`` indices) as spot lights, in that order;
        returns the nodes of the first ``n_shadowed``, which get shadows.

        The order is fixed for a given view whatever ``n_shadowed`` is: the shader sums lights in
        insertion order, and it looks shadows up only for the first ``n_shadowed`` spot lights.
        """
        shadowed = set()
        for k, (a, b) in enumerate(order):
            light = lights[a]
            gl_light = self._light(k)
            gl_light.color = light.color
            gl_light.intensity = light.intensity
            gl_light.outerConeAngle = light.outer_cone  # outer first: inner must not exceed it
            gl_light.innerConeAngle = light.inner_cone
            node = _add(scene, _gl_pose(*look_at(light.emitters[b])), light=gl_light)  # aimed at the centre
            if k < n_shadowed:
                shadowed.add(node)
        return shadowed

    def _light(self, k: int) -> pyrender.SpotLight:
        """The ``k``-th pooled spot light, with its own shadow map (allocated once)."""
        while len(self._lights) <= k:
            light = pyrender.SpotLight(outerConeAngle=np.pi / 4)
            light.shadow_texture = self._gl.new_shadow_map()
            self._lights.append(light)
        return self._lights[k]

    def _render_label(self, camera: Camera, texture: pyrender.Texture,
                      timings: dict[str, float] | None = None) -> np.ndarray:
        plain = Material(np.ones(4), 0.0, 1.0)
        with timed(timings, "graph"):
            scene, plane = self._new_scene(camera, 1.0, texture, plain)
        return self._gl.draw(scene, RenderFlags.FLAT, seen={plane}, timings=timings, step="label")[..., :3]


_SHARED: dict[tuple[int, tuple[int, int], int], SceneRenderer] = {}
_DISOWNED: list[SceneRenderer] = []
"""Renderers inherited from a parent process, kept alive and unused (see ``SceneRenderer.disown``)."""


def shared_renderer(image_size: tuple[int, int], shadow_map_size: int) -> SceneRenderer:
    """This process's renderer for these settings, created at first use and then reused.

    A forked child (a DataLoader worker) inherits its parent's renderers; it disowns them
    without touching their GL state and creates its own.
    """
    pid = os.getpid()
    for key in [k for k in _SHARED if k[0] != pid]:
        _SHARED.pop(key).disown()
    key = (pid, tuple(image_size), shadow_map_size)
    if key not in _SHARED:
        _SHARED[key] = SceneRenderer(image_size, shadow_map_size)
    return _SHARED[key]
