"""Unit occluder primitives (trimesh) and the painting's plane, as GPU meshes (``gpu.GpuMesh``).

Each unit primitive is centred at the origin and lies within the box ``|x_k| <= 1`` (the
scene sampler's bounding sphere relies on it): half-extent 1 along x and y for the sphere,
cube, cylinder, cone and torus (the torus 0.3 along z); the capsule is 0.5 wide and 2 long
along z; the icosahedron's vertices lie on the unit sphere; a ``hull`` is the convex hull of
random points on the unit sphere, one of ``sidar_torch.scene.SHAPES["hull"].variants`` fixed variants
(variant ``k`` drawn with ``default_rng(k)``); a ``prism`` is a random star-shaped polygon within
the unit disc extruded from z = -1 to 1, one of ``SHAPES["prism"].variants`` fixed
variants (likewise drawn). A scene's occluder scales, rotates and places it. Meshes are pooled:
a renderer uploads each pooled mesh once and reuses it with a new pose and material in every view.
"""

from __future__ import annotations

import functools
import math
from collections import defaultdict
from dataclasses import dataclass
from typing import Callable

import numpy as np
import trimesh

from .. import geometry
from ..scene import Occluder, ViewScene
from .gpu import GpuMesh
from .settings import RenderSettings
from .visibility import ball_pixel_radius, ball_shadow_pixel_radii

__all__ = ["FIXED_LEVEL", "MESHES", "MeshPool", "ShapeMesh", "detail_level", "level_gap", "mesh_level", "plane_mesh",
           "unit_primitive"]


def _hull(variant: int) -> trimesh.Trimesh:
    """Convex hull of 8-15 points drawn uniformly on the unit sphere (a pebble or crystal)."""
    rng = np.random.default_rng(variant)
    points = rng.normal(size=(rng.integers(8, 16), 3))
    return trimesh.convex.convex_hull(points / np.linalg.norm(points, axis=1, keepdims=True))


def _prism(variant: int) -> trimesh.Trimesh:
    """A star-shaped polygon of 5-9 vertices (angles sorted uniform draws at least 0.3 rad apart,
    radii in [0.4, 1]) extruded along z from -1 to 1: a beam, plank, star or wedge once scaled.

    The polygon is fanned from the origin, which sees every vertex (star-shaped), so no polygon
    triangulation library is needed (``trimesh.creation.extrude_polygon`` would need shapely).
    """
    rng = np.random.default_rng(variant)
    n = int(rng.integers(5, 10))
    while True:
        angles = np.sort(rng.uniform(0.0, 2 * np.pi, n))
        if np.diff(np.append(angles, angles[0] + 2 * np.pi)).min() >= 0.3:
            break
    radii = rng.uniform(0.4, 1.0, n)
    outline = np.column_stack([radii * np.cos(angles), radii * np.sin(angles)])
    fan = np.column_stack([np.zeros(n, int), 1 + np.arange(n), 1 + (np.arange(n) + 1) % n])
    prism = trimesh.creation.extrude_triangulation(np.vstack([[0.0, 0.0], outline]), fan, 2.0)
    return prism.apply_translation((0, 0, -1.0))


def _sagitta(radius: float, segments: int) -> float:
    """Largest gap between a circle of ``radius`` and its inscribed regular ``segments``-gon."""
    return radius * (1.0 - math.cos(math.pi / segments))


@functools.cache
def _icosphere(subdivisions: int) -> trimesh.Trimesh:
    return trimesh.creation.icosphere(subdivisions=subdivisions, radius=1.0)


@functools.cache
def _icosphere_gap(subdivisions: int) -> float:
    """1 - the least distance from the centre to a face plane: the inscribed polyhedron's largest
    gap to the unit sphere (exact: it is convex with its vertices on the sphere). Computed once per
    level: every view's mesh level asks for it (``detail_level``)."""
    mesh = _icosphere(subdivisions)
    return 1.0 - float(np.abs(np.einsum("ij,ij->i", mesh.face_normals, mesh.triangles[:, 0])).min())


@dataclass(frozen=True)
class _Level:
    """One level of detail of a curved primitive: how to build it and its largest gap to the true
    surface (unit-primitive units; the silhouette moves at most that far)."""

    build: Callable[[], trimesh.Trimesh]
    gap: Callable[[], float]


@dataclass(frozen=True)
class ShapeMesh:
    """How one occluder shape is meshed and shaded: a curved primitive by its ``levels`` of detail
    (coarsest first), an exact polyhedron by ``polyhedron`` (variant -> mesh, one level, no gap).

    Attributes:
        levels: the levels of a curved primitive (empty for a polyhedron).
        polyhedron: ``variant -> trimesh`` for a polyhedron, else None.
        smooth: shaded with smooth vertex normals (else flat face normals, or ``side_slope``'s).
        side_slope: a solid of revolution about z (radius 1, height 2): the z component of its
            side's outward normal before normalising, radius / height (:func:`_revolution_normals`).
    """

    levels: tuple[_Level, ...] = ()
    polyhedron: Callable[[int], trimesh.Trimesh] | None = None
    smooth: bool = False
    side_slope: float | None = None


def _shape_meshes() -> dict[str, ShapeMesh]:
    """Every shape's :class:`ShapeMesh`; the levels of curved primitives at :data:`FIXED_LEVEL` are
    the meshes used before levels existed (icosphere 3, 48 sections, capsule 32 x 16)."""
    def sphere(k):
        return _Level(lambda: _icosphere(k).copy(), lambda: _icosphere_gap(k))

    def cylinder(n):
        return _Level(lambda: trimesh.creation.cylinder(radius=1.0, height=2.0, sections=n), lambda: _sagitta(1.0, n))

    def cone(n):
        return _Level(lambda: trimesh.creation.cone(radius=1.0, height=2.0, sections=n).apply_translation((0, 0, -1.0)),
                      lambda: _sagitta(1.0, n))

    def torus(major, minor):
        return _Level(lambda: trimesh.creation.torus(major_radius=0.7, minor_radius=0.3, major_sections=major,
                                                     minor_sections=minor),
                      lambda: _sagitta(1.0, major) + _sagitta(0.3, minor))

    def capsule(latitude, around):
        # trimesh spans each quarter meridian with latitude / 2 segments: 2 * latitude per turn.
        return _Level(lambda: trimesh.creation.capsule(height=1.0, radius=0.5, count=(latitude, around)),
                      lambda: _sagitta(0.5, 2 * latitude) + _sagitta(0.5, around))

    return {
        "sphere": ShapeMesh(tuple(sphere(k) for k in (1, 2, 3, 4)), smooth=True),
        "cube": ShapeMesh(polyhedron=lambda _: trimesh.creation.box(extents=(2.0, 2.0, 2.0))),
        "cylinder": ShapeMesh(tuple(cylinder(n) for n in (12, 24, 48, 96)), side_slope=0.0),  # a vertical side
        "cone": ShapeMesh(tuple(cone(n) for n in (12, 24, 48, 96)), side_slope=0.5),
        "torus": ShapeMesh(tuple(torus(*mn) for mn in ((12, 6), (24, 12), (48, 24), (96, 48))), smooth=True),
        "capsule": ShapeMesh(tuple(capsule(*la) for la in ((8, 6), (16, 10), (32, 16), (64, 32))), smooth=True),
        "icosahedron": ShapeMesh(polyhedron=lambda _: trimesh.creation.icosahedron()),
        "hull": ShapeMesh(polyhedron=_hull),
        "prism": ShapeMesh(polyhedron=_prism),
    }


MESHES = _shape_meshes()
"""``SidarConfig.occluder_shapes`` name -> how it is meshed (the scene's facts of a shape are
``sidar_torch.scene.SHAPES``; ``tests/scene/test_scene.py`` checks both tables name the config's shapes)."""

FIXED_LEVEL = 2
"""The level every curved primitive had before levels of detail (``SidarConfig.mesh_detail`` "fixed")."""


_APEX_RINGS = 6
"""A cone's side facets are cut into strips at ``1 - 2 ** -j`` of the way to the apex, ``j = 1 ..
_APEX_RINGS`` (see :func:`_revolution_normals`)."""


def _revolution_normals(mesh: trimesh.Trimesh, slope: float) -> tuple[np.ndarray, np.ndarray]:
    """Per-corner positions and normals, each ``(3 F', 3)`` float32, of a cylinder or cone mesh
    (``slope``: :attr:`ShapeMesh.side_slope`): the side shaded with the true surface normal at each corner,
    the caps flat.

    A corner of a side face gets ``(cos a, sin a, slope)`` normalised, ``a`` its angle about z, so
    light varies smoothly around the side: no band per facet, and no seam along a quad's diagonal
    (both corners of an edge along the side share a normal, so each triangle interpolates in
    angle only). Cap faces (normal along z, ``|n_z| > 0.99``; a side's is at most
    ``0.5 / sqrt(1.25) = 0.45``) keep their face normal, so the rim stays sharp.

    A cone's apex has no normal of its own: a facet's apex corner can only take one angle (its
    middle), and across a row the normal would jump between facets by the apex's share of the
    interpolation. So each cone facet (base ``a``, ``b``, apex ``p``) is cut into strips at
    ``1 - 2 ** -j`` of the way from the base to the apex; every strip corner lies on a facet
    edge, where the angle is exact, and only the last triangle (the last ``2 ** -_APEX_RINGS`` of
    the height) meets the apex. The cuts lie on the facets' own edges, shared by both neighbours,
    so the surface, outline, masks and shadows are those of the flat-shaded mesh.
    """
    corners = mesh.vertices[mesh.faces]  # (F, 3, 3)
    cap = np.abs(mesh.face_normals[:, 2]) > 0.99
    on_axis = np.hypot(corners[..., 0], corners[..., 1]) < 1e-9  # (F, 3): a cone's apex corners
    pointed = ~cap & on_axis.any(axis=1)
    # Rotate each pointed facet's corners (keeping the winding) so that the apex comes last.
    apex_first = np.argmax(on_axis[pointed], axis=1)
    order = (apex_first[:, None] + np.array([1, 2, 3])) % 3
    a, b, apex = np.moveaxis(np.take_along_axis(corners[pointed], order[..., None], axis=1), 1, 0)
    cuts = 1.0 - 0.5 ** np.arange(_APEX_RINGS + 1)  # 0, 1/2, 3/4, ...
    lo, hi = cuts[:-1, None, None], cuts[1:, None, None]
    a0, b0, a1, b1 = (v + t * (apex - v) for v, t in ((a, lo), (b, lo), (a, hi), (b, hi)))
    strips = np.concatenate([np.stack([a0, b0, b1], axis=2), np.stack([a0, b1, a1], axis=2)]).reshape(-1, 3, 3)
    tips = np.stack([a + cuts[-1] * (apex - a), b + cuts[-1] * (apex - b), apex], axis=1)
    faces = np.concatenate([corners[~pointed], strips, tips])
    face_normals = np.concatenate([mesh.face_normals[~pointed], np.tile(mesh.face_normals[pointed], (2 * _APEX_RINGS, 1)),
                                   mesh.face_normals[pointed]])
    angles = np.arctan2(faces[..., 1], faces[..., 0])
    at_axis = np.hypot(faces[..., 0], faces[..., 1]) < 1e-9
    centroid = faces.mean(axis=1)
    angles = np.where(at_axis, np.arctan2(centroid[:, 1], centroid[:, 0])[:, None], angles)
    side = np.stack([np.cos(angles), np.sin(angles), np.full_like(angles, slope)], axis=-1)
    side /= np.linalg.norm(side, axis=-1, keepdims=True)
    flat = np.abs(face_normals[:, 2]) > 0.99
    normals = np.where(flat[:, None, None], face_normals[:, None, :], side)
    return faces.reshape(-1, 3).astype(np.float32), normals.reshape(-1, 3).astype(np.float32)


def _gl_mesh(shape: str, variant: int, level: int) -> GpuMesh:
    """The GPU mesh of a unit primitive, with the normals its shape is shaded with."""
    mesh, spec = unit_primitive(shape, variant, level), MESHES[shape]
    if spec.side_slope is not None:
        return GpuMesh(*_revolution_normals(mesh, spec.side_slope))
    return GpuMesh.from_trimesh(mesh, smooth=spec.smooth)


def unit_primitive(shape: str, variant: int = 0, level: int = FIXED_LEVEL) -> trimesh.Trimesh:
    """The unit primitive of ``shape`` as a trimesh (see module docstring for its size);
    ``variant`` picks a hull or prism (``0 <= variant < scene.SHAPES[shape].variants``)
    and is ignored by other shapes;
    ``level`` picks a curved primitive's level of detail (0 the coarsest, see :func:`detail_level`)
    and is ignored by polyhedra."""
    spec = MESHES[shape]
    if spec.polyhedron is not None:
        return spec.polyhedron(variant)
    return spec.levels[level].build()


def level_gap(shape: str, level: int) -> float:
    """Largest distance between the mesh of ``shape`` at ``level`` and the true surface, in
    unit-primitive units (0 for polyhedra)."""
    levels = MESHES[shape].levels
    return levels[level].gap() if levels else 0.0


def detail_level(shape: str, pixels_per_unit: float, max_error_px: float) -> int:
    """The coarsest level of ``shape`` whose silhouette stays within ``max_error_px`` of the true
    surface when one unit-primitive unit spans ``pixels_per_unit`` pixels on screen (the finest
    level when none does; 0 for polyhedra)."""
    levels = MESHES[shape].levels
    for level in range(len(levels)):
        if level_gap(shape, level) * pixels_per_unit <= max_error_px:
            return level
    return max(len(levels) - 1, 0)


def mesh_level(occ: Occluder, view: ViewScene, settings: RenderSettings) -> int:
    """The level of detail of ``occ``'s mesh in ``view`` (:data:`FIXED_LEVEL` unless
    ``settings.mesh_error_px`` is set).

    One unit of the unit primitive is ``max(scale)`` world units at most; on screen a world
    unit near the occluder spans about ``ball_pixel_radius / r`` pixels, ``r`` its bounding
    ball's radius, and on the painting under its shadow ``ball_shadow_pixel_radii / r``
    (the shadow may be the larger: an occluder near a light casts a magnified shadow). The
    larger of the two, over every emitter, sets the level: a silhouette gap of ``g`` units
    moves the outline and the shadow's edge by at most ``g`` times it, in pixels.
    """
    error_px = settings.mesh_error_px
    if error_px is None:
        return FIXED_LEVEL
    cam, radius = view.camera, float(np.linalg.norm(occ.scale))
    spans = [ball_pixel_radius(cam.K, cam.R, cam.t, occ.position, radius)] if settings.occluders_visible else []
    if settings.shadows and view.lights:
        emitters = np.concatenate([light.emitters for light in view.lights])
        spans.append(float(ball_shadow_pixel_radii(cam.K, cam.R, cam.t, emitters, occ.position, radius).max(initial=0.0)))
    return detail_level(occ.shape, max(spans, default=0.0) * float(occ.scale.max()) / radius, error_px)


class MeshPool:
    """GPU meshes of each shape, created on demand and reused (one GL upload each).

    ``take(shape, variant, k, level)`` returns the ``k``-th mesh of that shape, variant and level
    of detail, so a view with two spheres uses two distinct meshes (shadow-map keys name meshes),
    and a level chosen again in a later view is neither rebuilt nor uploaded again.
    """

    def __init__(self) -> None:
        self._meshes: dict[tuple[str, int, int], list[GpuMesh]] = defaultdict(list)

    def take(self, shape: str, variant: int, k: int, level: int = FIXED_LEVEL) -> GpuMesh:
        meshes = self._meshes[shape, variant, level]
        while len(meshes) <= k:
            meshes.append(_gl_mesh(shape, variant, level))
        return meshes[k]


def plane_mesh(image_size: tuple[int, int]) -> GpuMesh:
    """The painting: a rectangle in z = 0 facing +z, textured so that image row 0 is at the top
    (world +y) and column 0 at the left (world -x). Its material is set per view."""
    corners = geometry.plane_corners(image_size)  # top-left, top-right, bottom-right, bottom-left
    # The texture is uploaded flipped (gpu.PaintingTexture): t = 1 is the image's first row.
    uv = np.array([[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]])
    return GpuMesh(corners, np.tile(geometry.PLANE_NORMAL, (4, 1)), uv,
                   faces=np.array([[0, 3, 2], [0, 2, 1]]))  # counter-clockwise seen from +z
