"""Shadow maps: the pooled spot lights that carry them, the frustum each covers, and when a map
already holds what a draw would put in it.

Each emitter of a view becomes a :class:`~.draws.SpotEmitter` with the shadow map of its rank (a
layer of the shadow-map array, allocated once, at the first view with that many emitters). A map
is drawn again only when its key (the light's matrices, the map size and the casters) changed
since it was last drawn.
"""

from __future__ import annotations

import numpy as np

from ..geometry import clip_polygon, look_at, plane_corners, visible_halfplanes
from ..scene import Camera, SceneSequence, ViewScene
from .draws import SpotEmitter, Surface, ViewDraws, world_pose
from .passes import Passes
from .plan import soft_reach, soft_reach_balls
from .scene_graph import gl_pose
from .settings import RenderSettings
from .visibility import balls_may_be_seen, cube_corners, light_frusta

__all__ = ["SHADOW_MARGIN_TEXELS", "ShadowMaps"]

SHADOW_MARGIN_TEXELS = 2
"""Texels a fitted shadow map extends beyond its receivers: the filtered lookup reads half a texel
around a point, and a fitted window must not clamp it at the edge."""


class ShadowMaps:
    """The shadow maps of one renderer, one per emitter rank, and what each map holds.

    Args:
        passes: the renderer's passes (``render.passes``; hold the maps, compute the light matrices).
        settings: ``shadow_frustum``, ``occluders_visible``, ``image_size`` and ``reuse_shadow_maps`` count here.

    Attributes:
        layers: shadow maps allocated so far (the most emitters one view has used).
    """

    def __init__(self, passes: Passes, settings: RenderSettings):
        self._passes = passes
        self.settings = settings
        self.image_size = settings.image_size
        self.layers = 0
        self._held: dict[int, tuple] = {}  # layer -> key of what its shadow map holds

    def stale(self, keys: dict[SpotEmitter, tuple[int, tuple]]) -> list[SpotEmitter]:
        """The emitters of ``keys`` (:meth:`map_keys`) whose maps must be drawn: all of them unless
        ``settings.reuse_shadow_maps``, else those whose map holds something else."""
        reuse = self.settings.reuse_shadow_maps
        return [light for light, (k, key) in keys.items() if self._held.get(k) != key or not reuse]

    def drawn(self, keys: dict[SpotEmitter, tuple[int, tuple]]) -> None:
        """Record that the maps of ``keys`` now hold what their keys say."""
        self._held.update(keys.values())

    def add_lights(self, draws: ViewDraws, view: ViewScene, order: list[tuple[int, int]],
                   n_shadowed: int) -> list[SpotEmitter]:
        """Add the emitters ``order`` (``(light, emitter)`` indices of ``view.lights``) to ``draws.lights``,
        in that order; returns the first ``n_shadowed``, which get shadows. Each light
        carries its soft lookups' reach among ``view.occluders`` (``plan.soft_reach``) and, with
        ``settings.group_emitters``, its light's group: the number of its emitters and the pose of
        their centre (quirk 13; ``order`` keeps a light's emitters adjacent).

        The order is fixed for a given view whatever ``n_shadowed`` is: the shader sums lights in
        insertion order, and it looks shadows up only for the first ``n_shadowed`` spot lights.
        Each emitter gets the shadow map of its rank in ``(light, emitter)`` order, whatever its
        place in ``order``: views sharing the lights keep each emitter's map.
        """
        rank = {e: k for k, e in enumerate(sorted(order))}
        if order:  # room for every rank's map at once: one reallocation of the array, not one per new rank
            self._layer(len(order) - 1)
        group = self.settings.group_emitters
        # A light shaded as one (quirk 13) is shaded from its emitters' centre, aimed as they are.
        group_poses = {a: gl_pose(*look_at(view.lights[a].emitters.mean(axis=0)))
                       for a in {a for a, _ in order} if group and len(view.lights[a].emitters) > 1}
        light_radius = self.settings.light_radius
        centres, radii = soft_reach_balls(view, light_radius)
        shared: dict[int, dict] = {}  # per light: what its emitters share
        for a, b in order:
            light = view.lights[a]
            if a not in shared:
                if not 0.0 <= light.inner_cone <= light.outer_cone:
                    raise ValueError(f"light {a}: expected 0 <= inner_cone <= outer_cone, got {light.inner_cone}, "
                                     f"{light.outer_cone}")
                shared[a] = dict(color=np.asarray(light.color, np.float32), intensity=float(light.intensity),
                                 inner_cone=float(light.inner_cone), outer_cone=float(light.outer_cone),
                                 smooth_falloff=float(light.smooth_falloff),
                                 group_size=len(light.emitters) if a in group_poses else 1,
                                 group_pose=group_poses.get(a))
            draws.lights.append(SpotEmitter(
                pose=world_pose(gl_pose(*look_at(light.emitters[b]))),  # aimed at the centre
                layer=self._layer(rank[a, b]), soft_reach=soft_reach(light.emitters[b], centres, radii, light_radius),
                **shared[a]))
        return draws.lights[:n_shadowed]

    def _layer(self, k: int) -> int:
        """Layer ``k`` of the shadow-map array, allocated if new (growing it loses what the maps held)."""
        self.layers = max(self.layers, k + 1)
        if self._passes.shadow_maps.reserve(self.layers):
            self._held.clear()
        return k

    def frusta(self, shadowed: list[SpotEmitter], view: ViewScene, sequence: SceneSequence,
               canvas_sizes: list[tuple[int, int]] | None = None) -> dict[int, np.ndarray]:
        """Fitted frusta (:func:`~.visibility.light_frustum`, all at once: :func:`~.visibility.light_frusta`)
        of the ``shadowed`` emitters, keyed by ``id``, for ``"fitted"``; none for ``"cone"``, whose maps keep
        the cone's frustum (``passes.light_matrices``).

        A fitted map covers what its shadows must be right on (the *receivers*): the part of the
        painting, and the occluders, that the cameras see, over every view of the sequence with
        the same lights and occluders as this one. So with ``scene_per_view`` false a light gets
        the same frustum in every view (its map could be drawn once per sequence). Covering the whole
        painting and every occluder instead (view-independent too) measured 0.03-0.7 dB worse
        against a 4096 reference at 256-512 maps. Every occluder's ball counts as a caster. The
        window gets :data:`SHADOW_MARGIN_TEXELS` of margin. A light with no receiver in front
        of it keeps the cone's frustum. The cameras of ``sequence.views`` draw ``canvas_sizes`` ``(H, W)``
        pixels each (``render.canvas``; default ``image_size``).
        """
        frames = [self.image_size] * len(sequence.views) if canvas_sizes is None else list(canvas_sizes)
        if self.settings.shadow_frustum == "cone" or not shadowed:
            return {}
        casters = np.array([[*occ.position, np.linalg.norm(occ.scale)] for occ in view.occluders]).reshape(-1, 4)
        points = np.vstack([p for other, frame in zip(sequence.views, frames)
                            if other is view or (other.lights == view.lights and other.occluders == view.occluders)
                            for p in self._visible_receivers(other.camera, casters, frame)])
        margin = SHADOW_MARGIN_TEXELS / self._passes.shadow_map_size
        fitted = light_frusta([light.pose[:3, 3] for light in shadowed], [light.outer_cone for light in shadowed],
                              points, casters, margin, [light.soft_reach for light in shadowed])
        return {id(light): frustum for light, frustum in zip(shadowed, fitted) if frustum is not None}

    def _visible_receivers(self, cam: Camera, casters: np.ndarray, frame: tuple[int, int]) -> list[np.ndarray]:
        """World points ``(N, 3)`` bounding what ``cam`` sees over ``frame (H, W)`` pixels: the corners of
        the visible part of the painting and of the bounding cubes of the occluders that may be in view."""
        region = self._visible_region(cam, frame)
        points = [np.column_stack([region, np.zeros(len(region))])]
        if self.settings.occluders_visible:
            seen = balls_may_be_seen(cam.K, cam.R, cam.t, frame, casters[:, :3], casters[:, 3])
            points += [cube_corners(c[:3], c[3]) for c, visible in zip(casters, seen) if visible]
        return points

    def _visible_region(self, cam: Camera, frame: tuple[int, int]) -> np.ndarray:
        """``(N, 2)`` the convex part of the painting (plane ``z = 0``) that ``cam`` sees over ``frame (H, W)``."""
        halfplanes = visible_halfplanes(cam.K, cam.R, cam.t, frame)
        return clip_polygon(plane_corners(self.image_size)[:, :2], halfplanes)

    def map_keys(self, draws: ViewDraws, shadowed: list[SpotEmitter],
                 casters: list[Surface]) -> dict[SpotEmitter, tuple[int, tuple]]:
        """For each emitter of ``shadowed``, its map's layer and the key of the shadow map this view
        draws for it, ``casters`` being the surfaces drawn into the depth maps.

        A map is a function of the light's view and projection matrices (as the shadow pass
        computes them), its size, and each caster's mesh, pose and material (the depth pass is
        order-free: each texel keeps the nearest depth). A layer keeps its map from one
        draw to the next, so a map whose key is the one it was last drawn with already holds
        these texels and is not drawn again: with lights and occluders shared by every view
        (``plan``) each map is drawn by the first view that shadows its emitter, whatever the
        frustum rule, as long as it does not depend on the camera.
        """
        # The mesh objects themselves, not their ids: a key keeps its meshes alive, so no new mesh
        # can take the address of one it names.
        caster_key = frozenset((s.mesh, s.pose.tobytes(), s.material.base_color.tobytes()) for s in casters)
        keys = {}
        for light in shadowed:
            V, P = self._passes.matrices(draws, light)
            keys[light] = (light.layer, (V.tobytes(), P.tobytes(), self._passes.shadow_map_size, caster_key))
        return keys
