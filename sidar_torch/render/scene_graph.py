"""Scene descriptions as pyrender scene graphs: cameras, poses, clip ranges, materials, samplers.

The one place where the package's conventions (``sidar_torch.geometry``: OpenCV camera frame,
Kornia pixels) meet OpenGL's (y up, looking along -z, pixel centres at +0.5).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pyrender
from OpenGL import GL

from ..geometry import plane_corners
from ..scene import CAMERA_CLEARANCE, Camera, Material
from .pyrender_overrides import add_node
from .mirror import SurfaceMaterial, mirror_define

__all__ = ["GL_FROM_CV", "PAINTING_SAMPLERS", "FlatScene", "clip_range", "gl_camera", "gl_material", "gl_pose", "new_scene",
           "surface_factors", "transmission_factors"]

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


class FlatScene(pyrender.Scene):
    """A pyrender scene of one draw, whose nodes all hang from its root: each node's world pose and
    the scene's scale are computed once, as pyrender computes them.

    pyrender recomputes a pose from the scene graph at every ``get_pose`` (about 70 per view, for
    the shadow cameras, the uniforms and sorting) and the scale from the bounds at every shadow
    camera. Here a pose is kept while the node keeps its matrix (setting ``node.matrix`` or
    ``set_pose`` gives it a new one) and is in the scene, and is handed out read-only: a caller that
    changed it in place would raise rather than move the node for every later caller.
    """

    def __init__(self, **kwargs: Any):
        super().__init__(**kwargs)
        self._poses: dict[pyrender.Node, tuple[np.ndarray, np.ndarray]] = {}  # node -> (its matrix, pose)
        self._scale_of: tuple[np.ndarray, float] | None = None  # (the bounds it was computed from, scale)

    def add_node(self, node: pyrender.Node, parent_node: pyrender.Node | None = None) -> None:
        if parent_node is not None:
            raise ValueError("FlatScene.add_node: every node hangs from the root; got a parent_node")
        super().add_node(node)

    def get_pose(self, node: pyrender.Node) -> np.ndarray:
        """``(4, 4)`` float64 world pose of ``node`` (read-only; pyrender's value)."""
        matrix, pose = self._poses.get(node, (None, None))
        if matrix is None or matrix is not node._matrix:  # pyrender's _matrix: None until derived
            if node not in self.nodes:
                raise ValueError("Node must already be in scene")  # pyrender's check
            # pyrender's product along the node's path to the root, which is the node alone here
            # (no search of the scene graph for it).
            pose = np.dot(node.matrix, np.eye(4))
            pose.flags.writeable = False
            self._poses[node] = (node._matrix, pose)
        return pose

    def remove_node(self, node: pyrender.Node) -> None:
        self._poses.pop(node, None)
        super().remove_node(node)

    @property
    def scale(self) -> float:
        """The length of the diagonal of the scene's bounding box (pyrender's), kept until the
        bounds change (pyrender drops them when a node is added or removed)."""
        bounds = self.bounds
        if self._scale_of is None or self._scale_of[0] is not bounds:
            self._scale_of = (bounds, pyrender.Scene.scale.fget(self))
        return self._scale_of[1]


def gl_camera(camera: Camera, znear: float, zfar: float) -> tuple[pyrender.IntrinsicsCamera, np.ndarray]:
    """pyrender camera and its camera-to-world pose (OpenGL frame) for a Kornia-convention camera.

    The one place where pixel conventions meet: OpenGL puts pixel centres at +0.5 in window
    coordinates, Kornia at integers, so the principal point shifts by half a pixel (``cy``
    counts from the top row in both).
    """
    K = camera.K
    gl = pyrender.IntrinsicsCamera(fx=K[0, 0], fy=K[1, 1], cx=K[0, 2] + 0.5, cy=K[1, 2] + 0.5,
                                   znear=znear, zfar=zfar)
    return gl, gl_pose(camera.R, camera.t)


def gl_pose(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """pyrender node pose (camera-to-world, OpenGL axes: looks along -z) of the OpenCV-frame
    world-to-camera pose ``R, t``. Cameras and lights (which shine along -z) both use it."""
    world_from_cv = np.eye(4)
    world_from_cv[:3, :3] = R.T
    world_from_cv[:3, 3] = -R.T @ t
    return world_from_cv @ GL_FROM_CV


def clip_range(camera: Camera, image_size: tuple[int, int]) -> tuple[float, float]:
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


def surface_factors(specular: float, coat: float, coat_roughness: float) -> np.ndarray:
    """The ``(3,)`` float32 value of a material's ``emissiveFactor`` that ``shaders/surface.frag`` reads
    as specular level, clear-coat weight and clear-coat roughness (all in [0, 1]; ``programs`` quirk 5)."""
    return np.array([specular, coat, coat_roughness], dtype=np.float32)


def gl_material(material: Material, texture: pyrender.Texture | None = None) -> SurfaceMaterial:
    """pyrender's material for ``material``; untextured (an occluder's) it carries its program
    variant for reflecting or refracting the painting (``mirror``); the textured painting reflects
    only what lies above z = 0, never the painting, so it gets none."""
    base_color, metallic, specular = transmission_factors(material)
    return SurfaceMaterial(
        mirror=mirror_define(material) if texture is None else None,
        ior=material.ior,
        baseColorFactor=base_color,
        metallicFactor=metallic,
        roughnessFactor=float(material.roughness),
        emissiveFactor=surface_factors(specular, material.coat, material.coat_roughness),
        alphaMode="BLEND" if material.transparent else "OPAQUE",
        baseColorTexture=texture,
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


def new_scene(camera: Camera, ambient: float, painting: pyrender.Mesh, material: Material,
              texture: pyrender.Texture, image_size: tuple[int, int]) -> tuple[pyrender.Scene, pyrender.Node]:
    """A pyrender scene of one draw: the ``painting`` mesh (``meshes.plane_mesh``) with ``material`` and
    ``texture``, ambient light ``ambient`` and ``camera``; returns it and the painting's node.
    Occluders and lights are added by the caller."""
    # Alpha 0 where nothing is drawn: ``RenderedSequence.background``.
    scene = FlatScene(bg_color=(0.0, 0.0, 0.0, 0.0), ambient_light=np.full(3, ambient))
    painting.primitives[0].material = gl_material(material, texture)
    plane = add_node(scene, mesh=painting)
    gl_cam, pose = gl_camera(camera, *clip_range(camera, image_size))
    add_node(scene, pose, camera=gl_cam)
    return scene, plane
