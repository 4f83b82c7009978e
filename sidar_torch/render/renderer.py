"""The backend: a :class:`~sidar_torch.scene.SceneSequence` and a painting in, pixels out.

:class:`SceneRenderer` owns one offscreen GL context and everything uploaded to it (shader
programs, meshes, shadow maps, the current painting's texture) and reuses them for every
sample. Create it in the process that uses it (a DataLoader worker creates its own).

Per view it draws, in the camera's pixel grid (Kornia convention, see ``geometry``):

* the **view**: the painting under the view's ambient level and lights, with occluders and
  shadows; 8-bit sRGB (the shader's output encoding is exact sRGB, see ``programs``);
* the **mask**: a segmentation draw of the painting (white) and the camera-visible occluders
  (black) with depth testing, so occluder parts behind the painting never count; background
  and occluders are 1. Occluders less opaque than ``settings.mask_min_opacity`` are left out
  of this draw, so the painting seen through them counts as visible. With no such occluder in
  view the mask is the painting's outline, computed without a draw
  (:func:`~.visibility.painting_mask`);
* the **opacity** (only with ``settings.opacities``): an unlit draw of the painting (white, opaque) and every
  camera-visible occluder (black, with the alpha and Fresnel rise of the colour draw), blended
  as the colour draw blends them, so each pixel keeps the fraction of the painting that shows
  through (see :meth:`SceneRenderer._render_opacity`).

and once per sequence the **label**: the painting through view 0's camera, unlit and without
occluders (the texture as the reference camera samples it).

``SceneRenderer.render(..., timings=dict)`` adds the seconds spent in each step to the dict
(``upload``, ``graph``, ``shadow``, ``colour``, ``mask``, ``opacity``, ``label``, ``readback``; see
:meth:`_GLRenderer.draw` for how GL time is attributed).

Lights are spot lights (``scene`` explains how point and area lights map to them). The
painting is left out of shadow maps: a plane lit from its front cannot shadow itself, and
occluder parts behind it are farther from the light than the plane, so they cannot darken it
either. This removes shadow acne on the painting altogether.

What each view draws (which occluders, which emitters get shadows) is planned in ``plan``;
work that cannot change a pixel is skipped there and here, each skip with its reason.
"""

from __future__ import annotations

import os
import weakref
from collections import Counter
from dataclasses import dataclass
from typing import Any

import numpy as np
import pyrender
from OpenGL import GL
from pyrender.constants import MAX_N_LIGHTS, RenderFlags

from ..render_choices import MAX_SHADOWED_LIGHTS
from ..geometry import clip_polygon, look_at, plane_corners, visible_halfplanes
from ..scene import CAMERA_CLEARANCE, Camera, Light, Material, Occluder, SceneSequence, ViewScene
from ..timing import timed
from .context import open_context
from .framebuffer import FLIP_Y, Framebuffer, size_limits
from .meshes import FIXED_LEVEL, MeshPool, detail_level, plane_mesh
from .plan import ViewPlan, plan_views
from .programs import ProgramCache, surface_factors
from .settings import RenderSettings
from .transmittance import TransmittanceMaps, vertex_defines
from .visibility import (ball_may_be_seen, ball_pixel_radius, ball_shadow_pixel_radius, cube_corners,
                         light_frustum, painting_mask)

__all__ = ["RenderedSequence", "SceneRenderer", "shared_renderer"]

GL_FROM_CV = np.diag([1.0, -1.0, -1.0, 1.0])
"""Converts camera axes between the OpenCV frame (y down, z forward) and OpenGL's (y up, z back)."""

PAINTING_SAMPLERS = {  # keys: render_choices.TEXTURE_FILTERS
    "trilinear": pyrender.Sampler(magFilter=GL.GL_LINEAR, minFilter=GL.GL_LINEAR_MIPMAP_LINEAR,
                                  wrapS=GL.GL_CLAMP_TO_EDGE, wrapT=GL.GL_CLAMP_TO_EDGE),
    "bilinear": pyrender.Sampler(magFilter=GL.GL_LINEAR, minFilter=GL.GL_LINEAR,
                                 wrapS=GL.GL_CLAMP_TO_EDGE, wrapT=GL.GL_CLAMP_TO_EDGE),
}
"""The painting's texture filters (``RenderSettings.texture_filter``): trilinear blends mipmap levels
where a view shrinks the painting; bilinear reads the full-size texture only (aliases there).
Clamping keeps texels of the opposite edge out of the border pixels."""

SHADOW_MARGIN_TEXELS = 2
"""Texels a fitted shadow map extends beyond its receivers: the filtered lookup reads half a texel
around a point, and a fitted window must not clamp it at the edge."""

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
        background: ``(V, H, W)`` bool, True where the view's colour draw drew nothing (neither
            the painting nor an occluder): the draw clears to alpha 0 and every surface writes a
            positive alpha, except glass of opacity under about 0.06 over the background, whose
            blended alpha rounds to 0 in 8 bits.
        opacities: ``(V, H, W)`` uint8 or None (not asked for): 255 times the fraction of the
            painting hidden at each pixel (see :meth:`SceneRenderer._render_opacity`).
    """

    views: np.ndarray
    masks: np.ndarray
    label: np.ndarray
    background: np.ndarray
    opacities: np.ndarray | None = None


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
      previous painting, once a draw uses another); pooled meshes and shadow maps stay uploaded
      until :meth:`delete`;
    * every spot light can shade, with or without shadows (pyrender limits unshadowed lights
      to the 4 nearest);
    * shadow maps may be any power-of-two size;
    * forward passes draw upside down into its own single-sampled :class:`Framebuffer` (EGL
      contexts have no default framebuffer; ``framebuffer`` explains the orientation);
    * transparent casters tint and lighten their shadows through transmittance maps instead of
      darkening the depth maps (``render.transmittance``);
    * garbage collection issues no GL call (pyrender's ``__del__`` deletes its objects by id in
      whatever context is current, which may be another renderer's): the objects die with
      their context, which :class:`SceneRenderer` destroys.
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
        filters = sorted((n for n in casters if _transmits(n)), key=hash)  # hash: rank in the scene
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


class SceneRenderer:
    """Renders scene sequences in one offscreen GL context, as ``settings`` say.

    Args:
        settings: image size, shadow maps, filters, mesh detail, outputs and skips
            (:class:`~.settings.RenderSettings`).

    Attributes:
        settings: as given.
        skipped: counts of skipped work since creation: ``"occluders_culled"`` (per view),
            ``"masks_from_outline"`` (mask draws), ``"shadow_maps_reused"`` (shadow passes).

    Raises:
        ValueError: ``settings.image_size`` or ``shadow_map_size`` exceeds a limit of the GL context
            (:meth:`~.settings.RenderSettings.check_gl_limits`).
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
        self._gl = _GLRenderer(w, h, settings.shadow_map_size, settings.shadow_taps)
        GL.glPixelStorei(GL.GL_UNPACK_ALIGNMENT, 1)
        self._meshes = MeshPool()
        self._plane = plane_mesh(self.image_size)
        self._lights: list[pyrender.SpotLight] = []
        self._map_keys: dict[int, tuple] = {}  # pooled light index -> what its shadow map holds
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
                ``"colour"``, ``"mask"``, ``"opacity"`` and ``"label"`` (draw passes) and
                ``"readback"``; the pixels are the same either way.
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
        with timed(timings, "graph"):
            plans = plan_views(sequence, self.settings)
        views, masks, hidden = [], [], []
        for view, plan in zip(sequence.views, plans):
            image, mask, opacity = self._render_view(view, plan, sequence, texture, timings)
            views.append(image)
            masks.append(mask)
            hidden.append(opacity)
        label = self._render_label(sequence.views[0].camera, texture, timings)
        views = np.stack(views)
        return RenderedSequence(np.ascontiguousarray(views[..., :3]), np.stack(masks), label, views[..., 3] == 0,
                                np.stack(hidden) if self.settings.opacities else None)

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
            self._texture = pyrender.Texture(source=rgba, source_channels="RGBA",
                                             sampler=PAINTING_SAMPLERS[self.settings.texture_filter])
            self._painting = painting.copy()
        return self._texture

    def _new_scene(self, camera: Camera, ambient: float, texture: pyrender.Texture, material: Material):
        # Alpha 0 where nothing is drawn: ``RenderedSequence.background``.
        scene = pyrender.Scene(bg_color=(0.0, 0.0, 0.0, 0.0), ambient_light=np.full(3, ambient))
        self._plane.primitives[0].material = _gl_material(material, texture)
        plane = _add(scene, mesh=self._plane)
        gl_cam, pose = gl_camera(camera, *_clip_range(camera, self.image_size))
        _add(scene, pose, camera=gl_cam)
        return scene, plane

    def _render_view(self, view: ViewScene, plan: ViewPlan, sequence: SceneSequence, texture: pyrender.Texture,
                     timings: dict[str, float] | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """The view ``(H, W, 4)`` uint8 (RGB and the draw's alpha), its mask ``(H, W)`` bool and, with
        ``settings.opacities``, its opacity ``(H, W)`` uint8 (else None), drawing what ``plan`` says."""
        with timed(timings, "graph"):
            scene, plane = self._new_scene(view.camera, view.ambient, texture, view.plane_material)
            # Every occluder is added, culled or not: the scene's bounds set the depth range of the
            # shadow cameras (pyrender's ``scene.scale``). A culled one is just never drawn.
            nodes = []
            counts: dict[tuple[str, int], int] = {}
            for occ in view.occluders:
                key = (occ.shape, occ.variant, self._mesh_level(occ, view))
                mesh = self._meshes.take(*key[:2], counts.setdefault(key, 0), key[2])
                counts[key] += 1
                mesh.primitives[0].material = _gl_material(occ.material)
                nodes.append(_add(scene, occ.object_to_world(), mesh=mesh))
            self.skipped["occluders_culled"] += len(nodes) - len(plan.drawn | plan.casters)
            shadowed = self._add_lights(scene, view.lights, plan.order, plan.n_shadowed)
            casters = {nodes[i] for i in plan.casters}
            self._gl.shadow_frusta = self._shadow_frusta(shadowed, view, sequence)
            map_keys = self._shadow_map_keys(scene, shadowed, casters)
            stale = {node for node, (k, key) in map_keys.items()
                     if self._map_keys.get(k) != key or not self.settings.reuse_shadow_maps}
            self.skipped["shadow_maps_reused"] += len(shadowed) - len(stale)
        drawn = {nodes[i] for i in plan.drawn}
        # With no emitter that can cast a shadow on what the camera sees (the painting is not a
        # caster), the unshadowed draw gives the same pixels without the shadow passes.
        flags = RenderFlags.SHADOWS_SPOT if shadowed else RenderFlags.NONE
        image = self._gl.draw(scene, flags, seen={plane} | drawn, casters=casters, shadowed=shadowed,
                              timings=timings, step="colour", stale=stale)
        self._map_keys.update(map_keys.values())
        masked = {nodes[i] for i in plan.drawn
                  if view.occluders[i].material.base_color[3] >= self.settings.mask_min_opacity}
        if not masked and self.settings.masks_from_outline:
            # Only the painting would be drawn: its pixels are those whose centre sees it, which is
            # what the rasteriser's rule computes, up to its sub-pixel vertex snapping.
            self.skipped["masks_from_outline"] += 1
            with timed(timings, "mask"):
                mask = painting_mask(view.camera.K, view.camera.R, view.camera.t, self.image_size)
        else:
            seg_map = {plane: 255, **{node: 0 for node in masked}}
            seg = self._gl.draw(scene, RenderFlags.SEG, seen={plane} | masked, seg_node_map=seg_map,
                                timings=timings, step="mask")
            mask = seg[..., 0] < 128
        opacity = self._render_opacity(scene, plane, drawn, mask, timings) if self.settings.opacities else None
        return image, mask, opacity

    def _mesh_level(self, occ: Occluder, view: ViewScene) -> int:
        """The level of detail of ``occ``'s mesh in this view (:data:`~.meshes.FIXED_LEVEL` unless
        ``settings.mesh_error_px`` is set).

        One unit of the unit primitive is ``max(scale)`` world units at most; on screen a world
        unit near the occluder spans about ``ball_pixel_radius / r`` pixels, ``r`` its bounding
        ball's radius, and on the painting under its shadow ``ball_shadow_pixel_radius / r``
        (the shadow may be the larger: an occluder near a light casts a magnified shadow). The
        larger of the two, over every emitter, sets the level: a silhouette gap of ``g`` units
        moves the outline and the shadow's edge by at most ``g`` times it, in pixels.
        """
        error_px = self.settings.mesh_error_px
        if error_px is None:
            return FIXED_LEVEL
        cam, radius = view.camera, float(np.linalg.norm(occ.scale))
        spans = [ball_pixel_radius(cam.K, cam.R, cam.t, occ.position, radius)] if self.settings.occluders_visible else []
        if self.settings.shadows:
            spans += [ball_shadow_pixel_radius(cam.K, cam.R, cam.t, e, occ.position, radius)
                      for light in view.lights for e in light.emitters]
        return detail_level(occ.shape, max(spans, default=0.0) * float(occ.scale.max()) / radius, error_px)

    def _shadow_frusta(self, shadowed: set[pyrender.Node], view: ViewScene,
                       sequence: SceneSequence) -> dict[pyrender.Node, np.ndarray]:
        """Fitted frusta (:func:`~.visibility.light_frustum`) of the ``shadowed`` light
        nodes for ``"fitted"``; none for ``"cone"``, whose maps keep pyrender's frustum.

        A fitted map covers what its shadows must be right on (the *receivers*): the part of the
        painting, and the occluders, that the cameras see, over every view of the sequence with
        the same lights and occluders as this one. So with ``scene_per_view`` false a light gets
        the same frustum in every view (its map could be drawn once per sequence). Covering the whole
        painting and every occluder instead (view-independent too) measured 0.03-0.7 dB worse
        against a 4096 reference at 256-512 maps. Every occluder's ball counts as a caster. The
        window gets :data:`SHADOW_MARGIN_TEXELS` of margin. A light with no receiver in front
        of it keeps pyrender's frustum.
        """
        if self.settings.shadow_frustum == "cone" or not shadowed:
            return {}
        casters = np.array([[*occ.position, np.linalg.norm(occ.scale)] for occ in view.occluders]).reshape(-1, 4)
        points = np.vstack([p for other in sequence.views
                            if other.lights == view.lights and other.occluders == view.occluders
                            for p in self._visible_receivers(other.camera, casters)])
        margin = SHADOW_MARGIN_TEXELS / self._gl.shadow_map_size
        frusta = {node: light_frustum(node.matrix[:3, 3], node.light.outerConeAngle, points, casters, margin)
                  for node in shadowed}
        return {node: frustum for node, frustum in frusta.items() if frustum is not None}

    def _visible_receivers(self, cam: Camera, casters: np.ndarray) -> list[np.ndarray]:
        """World points ``(N, 3)`` bounding what ``cam`` sees: the corners of the visible part of
        the painting and of the bounding cubes of the occluders that may be in view."""
        region = self._visible_region(cam)
        points = [np.column_stack([region, np.zeros(len(region))])]
        if self.settings.occluders_visible:
            points += [cube_corners(c[:3], c[3]) for c in casters
                       if ball_may_be_seen(cam.K, cam.R, cam.t, self.image_size, c[:3], c[3])]
        return points

    def _visible_region(self, cam: Camera) -> np.ndarray:
        """``(N, 2)`` the convex part of the painting (plane ``z = 0``) that ``cam`` sees."""
        return clip_polygon(plane_corners(self.image_size)[:, :2], visible_halfplanes(cam.K, cam.R, cam.t, self.image_size))

    def _render_opacity(self, scene: pyrender.Scene, plane: pyrender.Node, visible: set[pyrender.Node],
                        mask: np.ndarray, timings: dict[str, float] | None = None) -> np.ndarray:
        """The view's opacity: ``(H, W)`` uint8, 255 times the fraction of the painting hidden.

        That is 255 outside the painting (background) and behind opaque occluders, 0 where the
        painting is seen unobstructed, and ``255 (1 - prod_k (1 - a_k))`` where transparent
        occluders ``k`` cover it, ``a_k`` being the opacity the colour draw blends them with: the
        material's alpha raised towards 1 by the Schlick-Fresnel reflectance of the view (4 % at
        normal incidence, all at grazing angles; ``programs`` quirk 5). The colour draw also makes
        a transparent occluder more opaque under its specular highlights; that light-dependent part
        is left out here (it would need a lit draw), so under a highlight the value is lower.

        An unlit draw of the ``scene`` the colour draw used (its materials are replaced; every view
        sets its own): the painting white and opaque, the ``visible`` occluders black with their
        alpha and blend mode, so each transparent layer multiplies what shows of the painting by
        ``1 - a_k`` whatever the order, and an opaque one zeroes it. pyrender sorts and
        depth-tests the occluders as in the colour draw (a transparent surface hides transparent
        surfaces behind it drawn later, as it does there), and occluder parts behind the painting
        fail the depth test. The framebuffer holds 8 bits, rounded after each blended layer: within
        1/255 of the exact value per transparent layer.

        With no visible occluder the draw would give the painting's coverage, which the ``mask``
        (``(H, W)`` bool, True off the painting) already is, so it is skipped.
        """
        if not visible:
            return mask.astype(np.uint8) * 255
        with timed(timings, "graph"):
            plane.mesh.primitives[0].material = _gl_material(Material(np.ones(4), 0.0, 1.0))
            for node in visible:
                primitive = node.mesh.primitives[0]
                black = np.array([0.0, 0.0, 0.0, primitive.material.baseColorFactor[3]])
                primitive.material = _gl_material(Material(black, 0.0, 1.0))
        shown = self._gl.draw(scene, RenderFlags.FLAT, seen={plane} | visible, timings=timings, step="opacity")
        return 255 - shown[..., 0]

    def _shadow_map_keys(self, scene: pyrender.Scene, shadowed: set[pyrender.Node],
                         casters: set[pyrender.Node]) -> dict[pyrender.Node, tuple[int, tuple]]:
        """For each node of ``shadowed``, its pooled light's index and the key of the shadow map
        this scene draws for it.

        A map is a function of the light's view and projection matrices (as the shadow pass
        computes them), its size, and each caster's mesh, pose and material (the depth pass is
        order-free: each texel keeps the nearest depth). A pooled light keeps its map from one
        draw to the next, so a map whose key is the one it was last drawn with already holds
        these texels and is not drawn again: with lights and occluders shared by every view
        (``plan``) each map is drawn by the first view that shadows its emitter, whatever the
        frustum rule, as long as it does not depend on the camera.
        """
        # The mesh objects themselves, not their ids: a key keeps its meshes alive, so no new mesh
        # can take the address of one it names.
        caster_key = frozenset((n.mesh, tuple(n.mesh.primitives), scene.get_pose(n).tobytes(),
                                n.mesh.primitives[0].material.baseColorFactor.tobytes()) for n in casters)
        keys = {}
        for node in shadowed:
            V, P = self._gl._get_light_cam_matrices(scene, node, RenderFlags.SHADOWS_SPOT)
            key = (V.tobytes(), P.tobytes(), self._gl.shadow_map_size, caster_key)
            keys[node] = (self._lights.index(node.light), key)
        return keys

    def _add_lights(self, scene: pyrender.Scene, lights: tuple[Light, ...], order: list[tuple[int, int]],
                    n_shadowed: int) -> set[pyrender.Node]:
        """Add the emitters ``order`` (``(light, emitter)`` indices) as spot lights, in that order;
        returns the nodes of the first ``n_shadowed``, which get shadows.

        The order is fixed for a given view whatever ``n_shadowed`` is: the shader sums lights in
        insertion order, and it looks shadows up only for the first ``n_shadowed`` spot lights.
        Each emitter gets the pooled light (and shadow map) of its rank in ``(light, emitter)``
        order, whatever its place in ``order``: views sharing the lights keep each emitter's map.
        """
        rank = {e: k for k, e in enumerate(sorted(order))}
        shadowed = set()
        for k, (a, b) in enumerate(order):
            light = lights[a]
            gl_light = self._light(rank[a, b])
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


_SHARED: dict[tuple, SceneRenderer] = {}
_DISOWNED: list[SceneRenderer] = []
"""Renderers inherited from a parent process, kept alive and unused (see ``SceneRenderer.disown``)."""


def shared_renderer(settings: RenderSettings) -> SceneRenderer:
    """This process's renderer for ``settings``, created at first use and then reused.

    A forked child (a DataLoader worker) inherits its parent's renderers; it disowns them
    without touching their GL state and creates its own.
    """
    pid = os.getpid()
    for key in [k for k in _SHARED if k[0] != pid]:
        _SHARED.pop(key).disown()
    key = (pid, settings)
    if key not in _SHARED:
        _SHARED[key] = SceneRenderer(settings)
    return _SHARED[key]
