"""Scene descriptions as draw-list rows: cameras, poses, clip ranges, materials, texture filters.

The one place where the package's conventions (``sidar_torch.geometry``: OpenCV camera frame,
Kornia pixels) meet OpenGL's (y up, looking along -z, pixel centres at +0.5).
"""

from __future__ import annotations

import numpy as np
from OpenGL import GL

from ..geometry import plane_corners
from ..scene import CAMERA_CLEARANCE, Camera, Material
from .draws import Surface, SurfaceMaterial, ViewDraws, perspective, world_pose
from .gpu import GpuMesh, PaintingTexture
from .mirror import mirror_define

__all__ = ["GL_FROM_CV", "PAINTING_FILTERS", "camera_draws", "clip_range", "gl_material", "gl_pose",
           "surface_factors", "transmission_factors", "view_draws"]

GL_FROM_CV = np.diag([1.0, -1.0, -1.0, 1.0])
"""Converts camera axes between the OpenCV frame (y down, z forward) and OpenGL's (y up, z back)."""


PAINTING_FILTERS = {  # keys: choices.render.TEXTURE_FILTERS; values: (min filter, mag filter, taps per pixel side)
    "trilinear": (GL.GL_LINEAR_MIPMAP_LINEAR, GL.GL_LINEAR, 1),
    "bilinear": (GL.GL_LINEAR, GL.GL_LINEAR, 1),
    "supersampled": (GL.GL_LINEAR_MIPMAP_LINEAR, GL.GL_LINEAR, 2),
}
"""The painting's texture filters (``RenderSettings.texture_filter``): trilinear blends mipmap levels
where a view shrinks the painting; bilinear reads the full-size texture only (aliases there);
supersampled averages 2 x 2 trilinear lookups spread over the pixel's footprint where a view shrinks
the painting, each at a finer level (``programs`` quirk 15: sharper oblique views, as a path tracer's).
The texture is clamped at its edges, which keeps texels of the opposite edge out of the border pixels."""


def camera_draws(camera: Camera, image_size: tuple[int, int],
                 canvas_size: tuple[int, int] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The camera-to-world pose (OpenGL axes, a ``draws.world_pose``) and OpenGL projection ``(4, 4)``
    of a Kornia-convention ``camera`` drawing ``canvas_size`` pixels (default ``image_size``, the
    painting's; ``render.canvas``), with :func:`clip_range`.

    The one place where pixel conventions meet: OpenGL puts pixel centres at +0.5 in window
    coordinates, Kornia at integers, so the principal point shifts by half a pixel (``cy``
    counts from the top row in both).
    """
    K = camera.K
    h, w = image_size if canvas_size is None else canvas_size
    projection = perspective(float(K[0, 0]), float(K[1, 1]), float(K[0, 2] + 0.5), float(K[1, 2] + 0.5), w, h,
                             *clip_range(camera, image_size, canvas_size))
    return world_pose(gl_pose(camera.R, camera.t)), projection


def gl_pose(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Camera-to-world pose (OpenGL axes: looks along -z) of the OpenCV-frame world-to-camera pose
    ``R, t``. Cameras and lights (which shine along -z) both use it."""
    world_from_cv = np.eye(4)
    world_from_cv[:3, :3] = R.T
    world_from_cv[:3, 3] = -R.T @ t
    return world_from_cv @ GL_FROM_CV


def clip_range(camera: Camera, image_size: tuple[int, int],
               canvas_size: tuple[int, int] | None = None) -> tuple[float, float]:
    """Near and far clip distances (painting units, along the optical axis) of ``camera`` drawing
    ``canvas_size`` pixels (default ``image_size``) of the painting of ``image_size``.

    Far lies beyond the painting's farthest corner. Near is far / 2000 (24-bit depth then resolves
    about 1e-4 painting units at the painting), or less for a camera closer to the painting than
    that: every painting point is at least the camera's height ``z`` away, and every occluder at
    least :data:`~sidar_torch.scene.CAMERA_CLEARANCE`; a point at distance ``r`` inside the view
    is at depth at least ``r cos(theta)``, ``theta`` the angle of the image's farthest corner
    from the axis. Near is half the smaller such depth.
    """
    zfar = 2.0 * float(np.linalg.norm(plane_corners(image_size) - camera.position, axis=1).max())
    h, w = image_size if canvas_size is None else canvas_size
    f = camera.K[0, 0]
    corner = np.hypot(max(camera.K[0, 2] + 0.5, w - 0.5 - camera.K[0, 2]), max(camera.K[1, 2] + 0.5, h - 0.5 - camera.K[1, 2]))
    cos_corner = f / np.hypot(f, corner)
    nearest = min(float(camera.position[2]), CAMERA_CLEARANCE) * cos_corner
    return min(zfar / 2000.0, nearest / 2), zfar


def surface_factors(specular: float, coat: float, coat_roughness: float) -> np.ndarray:
    """The ``(3,)`` float32 ``material.emissive_factor`` that ``shaders/surface.frag`` reads as specular
    level, clear-coat weight and clear-coat roughness (all in [0, 1]; ``programs`` quirk 5)."""
    return np.array([specular, coat, coat_roughness], dtype=np.float32)


def gl_material(material: Material, texture: PaintingTexture | None = None) -> SurfaceMaterial:
    """The shader's material for ``material``; untextured (an occluder's) it carries its program
    variant for reflecting or refracting the painting (``mirror``); the textured painting reflects
    only what lies above z = 0, never the painting, so it gets none.

    Raises:
        ValueError: a metallic or roughness factor outside [0, 1].
    """
    base_color, metallic, specular = transmission_factors(material)
    for name, value in (("metallic", metallic), ("roughness", material.roughness)):
        if not 0.0 <= value <= 1.0:
            raise ValueError(f"material {name}: expected a factor in [0, 1], got {value}")
    return SurfaceMaterial(
        base_color=np.asarray(base_color, np.float32),
        metallic=float(metallic),
        roughness=float(material.roughness),
        factors=surface_factors(specular, material.coat, material.coat_roughness),
        blend=bool(material.transparent),
        texture=texture,
        mirror=mirror_define(material) if texture is None else None,
        ior=float(material.ior),
    )


MAX_TRANSMISSION = 1.0 - 1e-6
"""The largest transmission :func:`transmission_factors` renders (1 is drawn as this)."""


def transmission_factors(material: Material) -> tuple[np.ndarray, float, float]:
    """The base colour factor ``(4,)`` float64, metallic and specular level the shader is given so that
    it draws ``material`` with its ``transmission`` ``t``: the diffuse light times ``1 - t``, the rest
    unchanged (the identity for ``t = 0``).

    The lit shader reads a material only through its diffuse colour ``c = 0.96 b (1 - m)`` and its
    normal-incidence reflectance ``f0 = 0.08 s (1 - m) + m b`` (``b`` the base colour, factor times
    texture, ``m`` metallic, ``s`` specular level; roughness and coat apart). With ``k = 1 - t (1 - m)``
    the factors ``b' = k b``, ``m' = m / k``, ``s' = s k / (1 - t)`` give ``c' = (1 - t) c`` and
    ``f0' = f0`` exactly, so no shader change is needed. ``t`` is capped at ``1 - 1e-6`` (a millionth of
    the diffuse light left, far below one 8-bit level), where ``k`` and ``1 - t`` are still positive and
    the float32 uniforms keep the dielectric reflectance to within a few per cent. The ambient term, ``b``
    times the ambient level, is scaled by ``k``; the paper's presets have no ambient light. Alpha is kept.
    """
    t = min(float(material.transmission), MAX_TRANSMISSION)
    m, s = float(material.metallic), float(material.specular)
    k = 1.0 - t * (1.0 - m)
    base = material.base_color.astype(np.float64)  # floats: ints would be read as 0-255
    base[:3] *= k
    return base, m / k, s * k / (1.0 - t)


def view_draws(camera: Camera, ambient: float, painting: GpuMesh, material: Material, texture: PaintingTexture,
               image_size: tuple[int, int], canvas_size: tuple[int, int] | None = None) -> ViewDraws:
    """The draw list of one view with the ``painting`` mesh (``meshes.plane_mesh``, of ``image_size``) in
    ``material`` and ``texture``, ambient light ``ambient`` and ``camera`` drawing ``canvas_size`` pixels
    (default ``image_size``); occluders and lights are added by the caller."""
    pose, projection = camera_draws(camera, image_size, canvas_size)
    plane = Surface(painting, world_pose(np.eye(4)), gl_material(material, texture))
    return ViewDraws(pose, projection, np.full(3, ambient, np.float32), plane)
