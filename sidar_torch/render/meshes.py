"""Unit occluder primitives (trimesh) and the painting's plane, as pyrender meshes.

Each unit primitive is centred at the origin and lies within the box ``|x_k| <= 1`` (the
scene sampler's bounding sphere relies on it): half-extent 1 along x and y for the sphere,
cube, cylinder, cone and torus (the torus 0.3 along z); the capsule is 0.5 wide and 2 long
along z; the icosahedron's vertices lie on the unit sphere; a ``hull`` is the convex hull of
random points on the unit sphere, one of :data:`sidar_torch.scene.HULL_VARIANTS` fixed variants
(variant ``k`` drawn with ``default_rng(k)``); a ``prism`` is a random star-shaped polygon within
the unit disc extruded from z = -1 to 1, one of :data:`sidar_torch.scene.PRISM_VARIANTS` fixed
variants (likewise drawn). A scene's occluder scales, rotates and places it. Meshes are pooled:
a renderer uploads each pooled mesh once and reuses it with a new pose and material in every view.
"""

from __future__ import annotations

from collections import defaultdict
from typing import Callable

import numpy as np
import pyrender
import trimesh

from .. import geometry

__all__ = ["MeshPool", "plane_mesh", "unit_primitive"]


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


_UNIT_PRIMITIVES: dict[str, Callable[[int], trimesh.Trimesh]] = {
    "sphere": lambda _: trimesh.creation.icosphere(subdivisions=3, radius=1.0),
    "cube": lambda _: trimesh.creation.box(extents=(2.0, 2.0, 2.0)),
    "cylinder": lambda _: trimesh.creation.cylinder(radius=1.0, height=2.0, sections=48),
    "cone": lambda _: trimesh.creation.cone(radius=1.0, height=2.0, sections=48).apply_translation((0, 0, -1.0)),
    "torus": lambda _: trimesh.creation.torus(major_radius=0.7, minor_radius=0.3, major_sections=48,
                                              minor_sections=24),
    "capsule": lambda _: trimesh.creation.capsule(height=1.0, radius=0.5, count=(32, 16)),
    "icosahedron": lambda _: trimesh.creation.icosahedron(),
    "hull": _hull,
    "prism": _prism,
}
_SMOOTH = {"sphere", "torus", "capsule"}
"""Shapes shaded with smooth vertex normals; the others keep sharp edges (flat face normals)."""


def unit_primitive(shape: str, variant: int = 0) -> trimesh.Trimesh:
    """The unit primitive of ``shape`` as a trimesh (see module docstring for its size);
    ``variant`` picks a hull or prism (``0 <= variant < scene.HULL_VARIANTS`` or ``PRISM_VARIANTS``)
    and is ignored by other shapes."""
    return _UNIT_PRIMITIVES[shape](variant)


class MeshPool:
    """pyrender meshes of each shape, created on demand and reused (one GL upload each).

    ``take(shape, variant, k)`` returns the ``k``-th mesh of that shape and variant, so a view
    with two spheres uses two distinct meshes (each carries its own material).
    """

    def __init__(self) -> None:
        self._meshes: dict[tuple[str, int], list[pyrender.Mesh]] = defaultdict(list)

    def take(self, shape: str, variant: int, k: int) -> pyrender.Mesh:
        meshes = self._meshes[shape, variant]
        while len(meshes) <= k:
            meshes.append(pyrender.Mesh.from_trimesh(unit_primitive(shape, variant), smooth=shape in _SMOOTH))
        return meshes[k]


def plane_mesh(image_size: tuple[int, int]) -> pyrender.Mesh:
    """The painting: a rectangle in z = 0 facing +z, textured so that image row 0 is at the top
    (world +y) and column 0 at the left (world -x). Its material is set per view."""
    corners = geometry.plane_corners(image_size)  # top-left, top-right, bottom-right, bottom-left
    # pyrender flips textures vertically on upload: t = 1 is the image's first row.
    uv = np.array([[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]])
    primitive = pyrender.Primitive(
        positions=corners.astype(np.float32),
        normals=np.tile(geometry.PLANE_NORMAL, (4, 1)).astype(np.float32),
        texcoord_0=uv.astype(np.float32),
        indices=np.array([[0, 3, 2], [0, 2, 1]], dtype=np.uint32),  # counter-clockwise seen from +z
    )
    return pyrender.Mesh([primitive])
