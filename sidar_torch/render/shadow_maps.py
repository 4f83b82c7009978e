"""Shadow maps: the pooled spot lights that carry them, the frustum each covers, and when a map
already holds what a draw would put in it.

Each emitter of a view becomes a pooled ``pyrender.SpotLight`` with its own shadow map (allocated
once, at the first view with that many emitters). A map is drawn again only when its key (the
light's matrices, the map size and the casters) changed since it was last drawn.
"""

from __future__ import annotations

import numpy as np
import pyrender
from pyrender.constants import RenderFlags

from ..geometry import clip_polygon, look_at, plane_corners, visible_halfplanes
from ..scene import Camera, SceneSequence, ViewScene
from .plan import soft_reach
from .pyrender_overrides import GLRenderer, ShadowedSpotLight, add_node
from .scene_graph import gl_pose
from .settings import RenderSettings
from .visibility import ball_may_be_seen, cube_corners, light_frustum

__all__ = ["SHADOW_MARGIN_TEXELS", "ShadowMaps"]

SHADOW_MARGIN_TEXELS = 2
"""Texels a fitted shadow map extends beyond its receivers: the filtered lookup reads half a texel
around a point, and a fitted window must not clamp it at the edge."""


class ShadowMaps:
    """The pooled spot lights of one renderer, each with its own shadow map, and what each map holds.

    Args:
        gl: the GL renderer (``pyrender_overrides.GLRenderer``; allocates the maps, computes the light matrices).
        settings: ``shadow_frustum``, ``occluders_visible``, ``image_size`` and ``reuse_shadow_maps`` count here.

    Attributes:
        lights: the pooled lights, in rank order.
    """

    def __init__(self, gl: GLRenderer, settings: RenderSettings):
        self._gl = gl
        self.settings = settings
        self.image_size = settings.image_size
        self.lights: list[pyrender.SpotLight] = []
        self._held: dict[int, tuple] = {}  # pooled light index -> key of what its shadow map holds

    def stale(self, keys: dict[pyrender.Node, tuple[int, tuple]]) -> set[pyrender.Node]:
        """The light nodes of ``keys`` (:meth:`map_keys`) whose maps must be drawn: all of them
        unless ``settings.reuse_shadow_maps``, else those whose map holds something else."""
        reuse = self.settings.reuse_shadow_maps
        return {node for node, (k, key) in keys.items() if self._held.get(k) != key or not reuse}

    def drawn(self, keys: dict[pyrender.Node, tuple[int, tuple]]) -> None:
        """Record that the maps of ``keys`` now hold what their keys say."""
        self._held.update(keys.values())

    def add_lights(self, scene: pyrender.Scene, view: ViewScene, order: list[tuple[int, int]],
                   n_shadowed: int) -> set[pyrender.Node]:
        """Add the emitters ``order`` (``(light, emitter)`` indices of ``view.lights``) as spot lights,
        in that order; returns the nodes of the first ``n_shadowed``, which get shadows. Each light
        carries its soft lookups' reach among ``view.occluders`` (``plan.soft_reach``) and, with
        ``settings.group_emitters``, its light's group: the number of its emitters and the pose of
        their centre (quirk 13; ``order`` keeps a light's emitters adjacent).

        The order is fixed for a given view whatever ``n_shadowed`` is: the shader sums lights in
        insertion order, and it looks shadows up only for the first ``n_shadowed`` spot lights.
        Each emitter gets the pooled light (and shadow map) of its rank in ``(light, emitter)``
        order, whatever its place in ``order``: views sharing the lights keep each emitter's map.
        """
        rank = {e: k for k, e in enumerate(sorted(order))}
        group = self.settings.group_emitters
        # A light shaded as one (quirk 13) is shaded from its emitters' centre, aimed as they are.
        group_poses = {a: gl_pose(*look_at(view.lights[a].emitters.mean(axis=0)))
                       for a in {a for a, _ in order} if group and len(view.lights[a].emitters) > 1}
        centres = np.array([occ.position for occ in view.occluders]).reshape(-1, 3)
        radii = np.array([np.linalg.norm(occ.scale) for occ in view.occluders])
        shadowed = set()
        for k, (a, b) in enumerate(order):
            light = view.lights[a]
            gl_light = self._light(rank[a, b])
            gl_light.color = light.color
            gl_light.intensity = light.intensity
            gl_light.outerConeAngle = light.outer_cone  # outer first: inner must not exceed it
            gl_light.innerConeAngle = light.inner_cone
            gl_light.smooth_falloff = light.smooth_falloff
            gl_light.soft_reach = soft_reach(light.emitters[b], centres, radii, self.settings.light_radius)
            gl_light.group_size = len(light.emitters) if a in group_poses else 1
            gl_light.group_pose = group_poses.get(a)
            node = add_node(scene, gl_pose(*look_at(light.emitters[b])), light=gl_light)  # aimed at the centre
            if k < n_shadowed:
                shadowed.add(node)
        return shadowed

    def _light(self, k: int) -> ShadowedSpotLight:
        """The ``k``-th pooled spot light, with its own shadow map: layer ``k`` of the renderer's
        ``shadow_maps`` (growing them loses what the maps held)."""
        while len(self.lights) <= k:
            self.lights.append(ShadowedSpotLight(len(self.lights), outerConeAngle=np.pi / 4))
        if self._gl.shadow_maps.reserve(len(self.lights)):
            self._held.clear()
        return self.lights[k]

    def frusta(self, shadowed: set[pyrender.Node], view: ViewScene,
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
        frusta = {node: light_frustum(node.matrix[:3, 3], node.light.outerConeAngle, points, casters, margin,
                                      node.light.soft_reach) for node in shadowed}
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
        halfplanes = visible_halfplanes(cam.K, cam.R, cam.t, self.image_size)
        return clip_polygon(plane_corners(self.image_size)[:, :2], halfplanes)

    def map_keys(self, scene: pyrender.Scene, shadowed: set[pyrender.Node],
                     casters: set[pyrender.Node]) -> dict[pyrender.Node, tuple[int, tuple]]:
        """For each node of ``shadowed``, its pooled light's index and the key of the shadow map
        this scene draws for it, ``casters`` being the nodes drawn into the depth maps.

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
            keys[node] = (self.lights.index(node.light), key)
        return keys
