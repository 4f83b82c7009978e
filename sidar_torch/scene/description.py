"""A SIDAR scene as plain data: cameras, materials, lights, occluders, views and sequences.

Nothing here knows OpenGL: a sequence can be sampled (:mod:`.sampler`), printed, compared and tested
without a renderer. All positions are world coordinates in painting units (see
``sidar_torch.config``); angles are radians; colours are linear RGB in [0, 1].

Every light is aimed at the painting's centre and is made of one or more *emitters*, each
rendered as a spot light: a spot light is one emitter; a point light is one emitter whose
inner cone covers the whole painting (on the painting this is exactly a point light, since a
point light is a spot light with an unbounded cone); an area light is several emitters
spread over a square facing the painting, whose shadows overlap into a penumbra (:mod:`.kinds`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

__all__ = ["FALLOFFS", "Camera", "Light", "Material", "Occluder", "SceneSequence", "ViewScene"]

FALLOFFS = {"quadratic": 0.0, "spot_blend": 1.0, "area_spread": 2.0}
"""A light's falloff profile between its cones (:attr:`Light.smooth_falloff`) -> the number the shader
reads (``cone_ramp`` in ``render/shaders/spot_light.glsl``, ``render.programs`` quirk 11), at angle ``a``
from the light's axis: ``quadratic``, pyrender's ``r**2`` with ``r = (cos a - cos outer) / (cos inner -
cos outer)`` clipped to [0, 1]; ``spot_blend``, Blender's spot blend ``smoothstep(r) = r**2 (3 - 2 r)``;
``area_spread``, Cycles' spread area light (``area_light_spread_attenuation``, a Lambertian soft box):
``cos a (1 - tan a / tan outer)`` inside the outer cone, the inner cone unused (0)."""


class _Plain:
    """Equality for frozen dataclasses holding numpy arrays (field by field, arrays by value)."""

    def __eq__(self, other: object) -> bool:
        if type(other) is not type(self):
            return NotImplemented
        pairs = ((getattr(self, f.name), getattr(other, f.name)) for f in dataclasses.fields(self))
        return all(np.array_equal(a, b) if isinstance(a, np.ndarray) else a == b for a, b in pairs)

    __hash__ = None  # type: ignore[assignment]


@dataclass(frozen=True, eq=False)
class Camera(_Plain):
    """A pinhole camera: intrinsics ``K (3, 3)`` in Kornia pixels and world-to-camera ``R (3, 3)``,
    ``t (3,)`` in the OpenCV frame, float64."""

    K: np.ndarray
    R: np.ndarray
    t: np.ndarray

    @property
    def position(self) -> np.ndarray:
        """Camera centre in world coordinates, ``(3,)``."""
        return -self.R.T @ self.t


@dataclass(frozen=True, eq=False)
class Material(_Plain):
    """A metallic-roughness surface with an optional clear coat (all factors in [0, 1]).

    Attributes:
        base_color: ``(4,)`` linear RGBA; alpha < 1 is blended (the opacity at normal incidence;
            towards grazing angles it rises with the Fresnel reflectance, see ``render.programs``).
        metallic, roughness: glTF metallic-roughness factors.
        specular: dielectric reflectance at normal incidence is ``0.08 * specular`` (Blender's
            convention; 0.5 is glTF's 4 %, 0 a purely diffuse dielectric).
        coat, coat_roughness: weight and roughness of a clear coat, a second specular lobe of 4 %
            reflectance over the base.
        transmission: the share of the dielectric base's diffuse light that passes through the
            surface instead (Blender's Principled ``Transmission Weight``): in the black world of a
            SIDAR scene it is lost, so the diffuse light is scaled by ``1 - transmission``; the
            specular lobes and the metallic part are unchanged.
        opaque_shadow: a blended (transparent) material whose shadow is as dark as an opaque one's
            (Cycles' glass and refraction: refracted light from a light source carries no direct
            light), instead of the tinted, lighter shadow of ``render.transmittance``.
        ior: index of refraction of a transparent body (1: none, light passes undeviated). Only a
            transparent material with ``ior > 1`` refracts (``render.mirror``).
    """

    base_color: np.ndarray
    metallic: float
    roughness: float
    specular: float = 0.5
    coat: float = 0.0
    coat_roughness: float = 0.0
    transmission: float = 0.0
    opaque_shadow: bool = False
    ior: float = 1.0

    @property
    def transparent(self) -> bool:
        return bool(self.base_color[3] < 1.0)


@dataclass(frozen=True, eq=False)
class Light(_Plain):
    """A light aimed at the painting's centre, made of ``S`` spot-light emitters.

    Attributes:
        kind: a name of :data:`~.kinds.LIGHT_KINDS` (``"spot"``, ``"point"`` or ``"area"``).
        emitters: ``(S, 3)`` emitter positions.
        color: ``(3,)`` linear RGB.
        intensity: each emitter's intensity, such that an emitter at distance ``d`` whose ray
            meets the painting at incidence angle ``theta`` gives it irradiance
            ``intensity * cos(theta) / d**2`` inside its inner cone.
        inner_cone, outer_cone: half-angles (rad). Between them the light falls off as ``r**2``
            (pyrender's), ``r = (cos a - cos outer) / (cos inner - cos outer)`` at angle ``a`` from
            the axis, or as ``smooth_falloff`` says.
        smooth_falloff: the falloff profile, a value of :data:`FALLOFFS` (``False``/``True`` read as
            ``quadratic``/``spot_blend``).
    """

    kind: str
    emitters: np.ndarray
    color: np.ndarray
    intensity: float
    inner_cone: float
    outer_cone: float
    smooth_falloff: float = 0.0


@dataclass(frozen=True, eq=False)
class Occluder(_Plain):
    """A unit primitive (``shape``, within the box ``|x_k| <= 1``; ``variant`` picks one of the
    fixed meshes of its shape, :attr:`~.kinds.Shape.variants` in :data:`~.kinds.SHAPES`) scaled by ``scale (3,)``, rotated by
    ``rotation (3, 3)`` and centred at ``position (3,)``."""

    shape: str
    position: np.ndarray
    rotation: np.ndarray
    scale: np.ndarray
    material: Material
    variant: int = 0

    def object_to_world(self) -> np.ndarray:
        """``(4, 4)`` float64 transform from the unit primitive's frame to the world."""
        m = np.eye(4)
        m[:3, :3] = self.rotation * self.scale[None, :]
        m[:3, 3] = self.position
        return m


@dataclass(frozen=True, eq=False)
class ViewScene(_Plain):
    """What one view renders: its camera, lights, occluders, painting material and ambient level."""

    camera: Camera
    lights: tuple[Light, ...]
    occluders: tuple[Occluder, ...]
    plane_material: Material
    ambient: float


@dataclass(frozen=True, eq=False)
class SceneSequence(_Plain):
    """One sample's scenes: the painting (size only; pixels come from a source) and ``V`` views.

    Attributes:
        image_size: ``(H, W)`` of every view, in pixels.
        views: ``V`` view scenes; view 0's camera is the fronto-parallel reference.
        lens_model: ``"none"`` (pinhole cameras) or a row of ``sidar_torch.choices.lenses.LENS_MODELS``.
        lenses: with a lens, ``(V, 5)`` float64, each view's coefficients in normalised camera
            coordinates (``sidar_torch.choices.lenses``); None without.

    How it is drawn (shadows, occluders seen by the cameras, masks) is the renderer's business
    (``sidar_torch.render.RenderSettings``), not the scene's.
    """

    image_size: tuple[int, int]
    views: tuple[ViewScene, ...]
    lens_model: str = "none"
    lenses: np.ndarray | None = None

    def cameras(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Stacked ``K (V, 3, 3)``, ``R (V, 3, 3)``, ``t (V, 3)`` float64."""
        cams = [v.camera for v in self.views]
        return np.stack([c.K for c in cams]), np.stack([c.R for c in cams]), np.stack([c.t for c in cams])
