"""A view's draw list: what the passes draw, as plain data (no scene graph).

``render.renderer`` builds one :class:`ViewDraws` per view from its ``ViewScene`` and ``ViewPlan``
(``scene_graph`` converts cameras, poses and materials); ``render.passes`` draws it. Surfaces and
lights are kept in their insertion order, the painting first: the order the shader sums lights in,
and the one ``plan`` puts the shadowed emitters first in.

Frames: poses are ``(4, 4)`` float64 object-to-world matrices; cameras and lights use OpenGL's axes
(looking along their -z, y up; ``scene_graph.gl_pose``); world units are painting units.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np

from .gpu import GpuMesh, PaintingTexture

__all__ = ["SpotEmitter", "Surface", "SurfaceMaterial", "ViewDraws", "perspective", "world_pose"]


def world_pose(matrix: np.ndarray) -> np.ndarray:
    """``(4, 4)`` float64 world pose of an object placed with ``matrix``: the product with the
    identity, as pyrender composed a root node's pose (signed zeros become +0), so that every
    matrix the passes hand to GL is bit for bit the one the stored digests were recorded with."""
    return np.dot(matrix, np.eye(4))


@dataclass(frozen=True, eq=False)
class SurfaceMaterial:
    """What the surface shader reads of a material (``scene_graph.gl_material`` makes it).

    Attributes:
        base_color: ``(4,)`` float32 linear RGBA factor (times the texture, if any).
        metallic, roughness: in [0, 1].
        factors: ``(3,)`` float32 specular level, clear-coat weight and roughness (``programs`` quirk 5).
        blend: alpha-blended (transparent material) rather than opaque.
        texture: the painting's texture for the painting, else None.
        mirror: the program define that reflects or refracts the painting (``mirror.mirror_define``), or None.
        ior: index of refraction (glass), 1 otherwise.
    """

    base_color: np.ndarray
    metallic: float
    roughness: float
    factors: np.ndarray
    blend: bool = False
    texture: PaintingTexture | None = None
    mirror: str | None = None
    ior: float = 1.0

    @property
    def transparent(self) -> bool:
        """Drawn after the opaque surfaces, farthest first: blended with an alpha below 1 (a
        blended material of alpha 1 is drawn among the opaque ones, with blending on)."""
        return self.blend and float(self.base_color[3]) < 1.0


@dataclass(eq=False)
class Surface:
    """One mesh of a view: ``pose`` ``(4, 4)`` (a :func:`world_pose`) and its material."""

    mesh: GpuMesh
    pose: np.ndarray
    material: SurfaceMaterial

    @functools.cached_property
    def corners(self) -> np.ndarray:
        """``(8, 3)`` world corners of the mesh's box under :attr:`pose` (``GpuMesh.corners``), computed at
        the first use and kept: a view's depth range (:attr:`ViewDraws.scale`) and its shadow maps' written
        texels (``passes``) both ask for them. The pose is not changed after that."""
        return self.mesh.corners(self.pose)


@dataclass(eq=False)
class SpotEmitter:
    """One spot light as the shader shades it (``programs`` quirks 11-13).

    Attributes:
        pose: ``(4, 4)`` light-to-world (OpenGL axes: shines along its -z), a :func:`world_pose`.
        color: ``(3,)`` float32 linear RGB; intensity: candela.
        inner_cone, outer_cone: radians.
        layer: its shadow map's layer in the shadow-map array (its rank in the renderer's pool).
        smooth_falloff: 1 Blender's smoothstep between the cones, 0 pyrender's squared ramp.
        soft_reach: how far its soft lookups search the map (``plan.soft_reach``; tangent units).
        group_size: emitters shaded together, this one and the next ones (quirk 13).
        group_pose: ``(4, 4)`` pose the group is shaded from, or None (its own).
    """

    pose: np.ndarray
    color: np.ndarray
    intensity: float
    inner_cone: float
    outer_cone: float
    layer: int
    smooth_falloff: float = 0.0
    soft_reach: float = 0.0
    group_size: int = 1
    group_pose: np.ndarray | None = None
    matrices: tuple[np.ndarray, np.ndarray] | None = field(default=None, repr=False)
    """``(V, P)`` of its shadow map once computed (``passes.light_matrices``)."""


def perspective(fx: float, fy: float, cx: float, cy: float, width: int, height: int, znear: float,
                zfar: float) -> np.ndarray:
    """OpenGL projection ``(4, 4)`` float64 of a pinhole camera in window pixels (``cx, cy`` with
    pixel centres at +0.5, ``cy`` from the top row), as pyrender's ``IntrinsicsCamera`` builds it."""
    P = np.zeros((4, 4))
    P[0][0] = 2.0 * fx / float(width)
    P[1][1] = 2.0 * fy / float(height)
    P[0][2] = 1.0 - 2.0 * cx / float(width)
    P[1][2] = 2.0 * cy / float(height) - 1.0
    P[3][2] = -1.0
    P[2][2] = (zfar + znear) / (znear - zfar)
    P[2][3] = (2 * zfar * znear) / (znear - zfar)
    return P


@dataclass(eq=False)
class ViewDraws:
    """The draw list of one view.

    Attributes:
        camera_pose: ``(4, 4)`` camera-to-world (OpenGL axes), a :func:`world_pose`.
        projection: ``(4, 4)`` the camera's OpenGL projection (upright; the passes flip it).
        ambient: ``(3,)`` float32 ambient light.
        painting: the painting's surface.
        occluders: every occluder of the view, culled ones included (they set :attr:`scale`), in order.
        lights: the spot emitters, in the shader's order (shadowed ones first).
    """

    camera_pose: np.ndarray
    projection: np.ndarray
    ambient: np.ndarray
    painting: Surface
    occluders: list[Surface] = field(default_factory=list)
    lights: list[SpotEmitter] = field(default_factory=list)

    @property
    def surfaces(self) -> list[Surface]:
        """The painting, then the occluders."""
        return [self.painting, *self.occluders]

    @functools.cached_property
    def scale(self) -> float:
        """The diagonal of the box around every surface (world units): sets the default shadow
        cameras' depth range (pyrender's ``Scene.scale``). Computed at its first use, which comes
        after every surface is listed (the shadow frusta), then kept: the passes ask for it per light."""
        corners = np.vstack([surface.corners for surface in self.surfaces])
        return float(np.linalg.norm(np.diff(np.array([corners.min(axis=0), corners.max(axis=0)]), axis=0).reshape(-1)))

    def ordered(self, surfaces: list[Surface]) -> list[Surface]:
        """``surfaces`` in draw order: the opaque ones nearest first (the depth test then rejects the
        fragments an occluder hides before they are shaded; opaque draws do not blend, so the order
        changes no pixel), then the transparent ones farthest first, which their blending needs.
        Distances are from the camera to each surface's origin."""
        camera = self.camera_pose[:3, 3]
        distance = {id(s): np.linalg.norm(s.pose[:3, 3] - camera) for s in surfaces}
        opaque = sorted((s for s in surfaces if not s.material.transparent), key=lambda s: distance[id(s)])
        blended = sorted((s for s in surfaces if s.material.transparent), key=lambda s: -distance[id(s)])
        return opaque + blended
