"""The kinds a scene is made of, as tables: :data:`LIGHT_KINDS`, :data:`MATERIAL_KINDS`,
:data:`SHAPES`, keyed by the names ``SidarConfig`` accepts (``light_types``, ``occluder_materials``,
``occluder_shapes``; ``tests/scene/test_scene.py`` checks that config, these tables and the
renderer's meshes name the same kinds).

Each row draws from a numpy ``Generator`` in a fixed order (the draws of a kind never depend on
another kind's row), so a sequence stays a pure function of ``(config, rng)``. Adding a kind is a
row here, its name in ``config.allowed`` and, for a shape, its mesh in ``render.meshes``.
"""

from __future__ import annotations

import colorsys
import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from .. import geometry
from ..config import SidarConfig
from .description import FALLOFFS, Material, Occluder

__all__ = ["CONE_MARGIN", "LIGHT_KINDS", "MATERIAL_KINDS", "MAX_EMITTER_CONE", "PAPER_TORUS_SCALE", "ROUGHNESS_RANGES",
           "SHAPES",
           "Beam", "LightKind", "Shape", "SimpleMaterial", "occluder_radius", "spread_beam"]

MAX_EMITTER_CONE = 1.0
"""Largest outer half-angle (rad) of an emitter's cone: wider shadow frusta give shadow acne."""

CONE_MARGIN = math.radians(1.0)
"""Angle by which a painting-covering cone exceeds the painting's farthest corner."""


# --------------------------------------------------------------------------- lights


@dataclass(frozen=True)
class Beam:
    """What a light kind makes of a light's drawn position and irradiance at the painting's centre.

    Attributes:
        position: ``(3,)`` the light's centre (moved back from the drawn one if its emitters'
            cones could not cover the painting, see :func:`_covering_emitters`).
        emitters: ``(S, 3)`` emitter positions.
        inner_cone, outer_cone: half-angles (rad).
        irradiance: each emitter's irradiance at the painting's centre.
        smooth_falloff: the falloff between the cones, a value of ``description.FALLOFFS``.
    """

    position: np.ndarray
    emitters: np.ndarray
    inner_cone: float
    outer_cone: float
    irradiance: float
    smooth_falloff: float = FALLOFFS["quadratic"]


@dataclass(frozen=True)
class LightKind:
    """One kind of light.

    Attributes:
        irradiance: the ``SidarConfig`` range field its irradiance at the painting's centre is drawn from.
        intensity: the range field its intensity is drawn from instead, unless that is ``(0, 0)``.
        beam: ``(config, rng, position (3,), irradiance, image_size) -> Beam``: its emitters and cones.
    """

    irradiance: str
    intensity: str
    beam: Callable[[SidarConfig, np.random.Generator, np.ndarray, float, tuple[int, int]], Beam]


def _spot_beam(config: SidarConfig, rng: np.random.Generator, position: np.ndarray, irradiance: float,
               size: tuple[int, int]) -> Beam:
    """One emitter with a drawn cone (``spot_cone_deg``) and a drawn blend ``u`` that sets its inner
    cone as ``spot_falloff`` says (``quadratic``: ``outer (1 - u)``; ``blender``: Blender's spot blend,
    ``cos inner = cos outer + (1 - cos outer) u``, with the smoothstep falloff)."""
    outer = min(math.radians(rng.uniform(*config.spot_cone_deg)) / 2, MAX_EMITTER_CONE)
    blend = rng.uniform()
    if config.spot_falloff == "blender":
        inner = math.acos(math.cos(outer) + (1.0 - math.cos(outer)) * blend)
        return Beam(position, position[None], inner, outer, irradiance, FALLOFFS["spot_blend"])
    return Beam(position, position[None], outer * (1.0 - blend), outer, irradiance)


def _point_beam(config: SidarConfig, rng: np.random.Generator, position: np.ndarray, irradiance: float,
                size: tuple[int, int]) -> Beam:
    """One emitter whose inner cone covers the whole painting: a point light, on the painting."""
    return _covering_beam(position, np.zeros((1, 2)), irradiance, size)


def _area_beam(config: SidarConfig, rng: np.random.Generator, position: np.ndarray, irradiance: float,
               size: tuple[int, int]) -> Beam:
    """``area_light_samples`` emitters drawn on a square of side ``area_light_size`` facing the
    painting, sharing the irradiance; narrowed by ``area_spread_deg`` (:func:`spread_beam`) unless
    it is 180 degrees."""
    n = config.area_light_samples
    offsets = rng.uniform(-0.5, 0.5, size=(n, 2)) * config.area_light_size
    beam = _covering_beam(position, offsets, irradiance, size)
    if config.area_spread_deg != (180.0, 180.0):
        inner, outer, centre = spread_beam(rng.uniform(*config.area_spread_deg), irradiance)
        beam = Beam(beam.position, beam.emitters, inner, outer, centre / n, FALLOFFS["area_spread"])
    return beam


def _covering_beam(position: np.ndarray, offsets: np.ndarray, irradiance: float, size: tuple[int, int]) -> Beam:
    """Emitters at ``offsets (S, 2)`` around ``position`` whose inner cones cover the painting,
    sharing ``irradiance`` so that their sum is the drawn one."""
    position, emitters, inner = _covering_emitters(position, offsets, size)
    return Beam(position, emitters, inner, inner + CONE_MARGIN, irradiance / len(offsets))


LIGHT_KINDS: dict[str, LightKind] = {
    "spot": LightKind("spot_irradiance", "spot_intensity", _spot_beam),
    "point": LightKind("light_irradiance", "light_intensity", _point_beam),
    "area": LightKind("area_irradiance", "area_intensity", _area_beam),
}
"""``SidarConfig.light_types`` name -> how that kind of light is drawn."""


def spread_beam(spread_deg: float, irradiance: float) -> tuple[float, float, float]:
    """Inner and outer cone (rad) and centre irradiance of an area light narrowed by Blender's
    ``spread`` (full angle, degrees) whose unnarrowed centre irradiance is ``irradiance``; the beam's
    falloff is ``FALLOFFS["area_spread"]``.

    Cycles (``area_light_spread_attenuation``) keeps a spread light's power and scales its radiance by
    ``(tan a - tan t) / (tan a - a)`` at angle ``t`` from its axis, ``a = spread / 2``: with the
    emitter's Lambertian ``cos t``, an intensity ``cos t (1 - tan t / tan a)`` times its peak, which is
    ``tan a / (tan a - a)`` times the unnarrowed light's (the integral of ``cos t (tan a - tan t)`` over
    the cone is ``pi (tan a - a)``, the unnarrowed emitter's ``pi`` over ``tan a - a``). Here the beam is a
    spot with no inner cone and that profile. ``a`` is capped at :data:`MAX_EMITTER_CONE`.
    """
    outer = min(math.radians(spread_deg) / 2, MAX_EMITTER_CONE)
    return 0.0, outer, irradiance * math.tan(outer) / (math.tan(outer) - outer)


def _cover_angle(emitter: np.ndarray, size: tuple[int, int]) -> float:
    """Largest angle (rad) between the emitter's axis (towards the centre) and a painting corner,
    plus :data:`CONE_MARGIN`."""
    axis = -emitter / np.linalg.norm(emitter)
    rays = geometry.plane_corners(size) - emitter
    cos = rays @ axis / np.linalg.norm(rays, axis=1)
    return float(np.arccos(np.minimum(np.maximum(cos, -1.0), 1.0)).max()) + CONE_MARGIN  # np.clip's values


def _covering_emitters(position: np.ndarray, offsets: np.ndarray, size: tuple[int, int]):
    """Emitters at ``offsets (S, 2)`` on a square centred at ``position`` and facing the origin,
    moved away from the centre along its ray until every emitter's painting-covering cone fits
    within :data:`MAX_EMITTER_CONE` (no move if they already do).

    Returns:
        the (possibly moved) centre ``(3,)``, the emitters ``(S, 3)`` and the largest of their
        :func:`_cover_angle` (rad).
    """
    while True:
        u, v, _ = geometry.look_at(position)[0]  # the square's axes: a camera's x and y there
        emitters = position + offsets[:, :1] * u + offsets[:, 1:] * v
        angle = max(_cover_angle(e, size) for e in emitters)
        if angle <= MAX_EMITTER_CONE - CONE_MARGIN:
            return position, emitters, angle
        position = position * 1.25


# --------------------------------------------------------------------------- occluder materials


ROUGHNESS_RANGES = {"glossy": (0.05, 0.3), "metallic": (0.05, 0.4), "transparent": (0.05, 0.5)}
"""The roughness ranges of the simple kinds that draw one. Every simple kind draws all three, in this
order, and keeps its own (if any): the draws of every sample recorded since the first release
(``tests/stored_digests.py``) depend on it."""


PAPER_ROUGHNESS = (0.0, 0.5)
"""The paper's roughness range for every occluder material (``SidarConfig.paper_occluder_materials``)."""


def _colour(rng: np.random.Generator, config: SidarConfig) -> tuple[float, float, float]:
    """An occluder's linear RGB colour from three draws: HSV with hue and saturation in [0, 1] and value
    in [0.2, 1], or, with ``paper_occluder_materials``, each channel uniform in [0, 1] (Blender's
    ``np.random.uniform(0, 1, 4)`` colour input, linear)."""
    if config.paper_occluder_materials:
        return tuple(rng.uniform(size=3))
    return colorsys.hsv_to_rgb(rng.uniform(), rng.uniform(), rng.uniform(0.2, 1.0))


@dataclass(frozen=True)
class SimpleMaterial:
    """A material kind with one colour draw and named ranges, drawn in this order: colour
    (:func:`_colour`), ``alpha`` if a range, then every range of :data:`ROUGHNESS_RANGES` (each
    :data:`PAPER_ROUGHNESS` with ``paper_occluder_materials``).

    Attributes:
        alpha: opacity, or a range it is drawn from (transparent).
        metallic, specular: fixed factors.
        roughness: fixed, or the name of its range in :data:`ROUGHNESS_RANGES`.
    """

    alpha: float | tuple[float, float]
    metallic: float
    roughness: float | str
    specular: float

    def __call__(self, rng: np.random.Generator, config: SidarConfig) -> Material:
        rgb = _colour(rng, config)
        alpha = rng.uniform(*self.alpha) if isinstance(self.alpha, tuple) else self.alpha
        paper = config.paper_occluder_materials
        drawn = {name: rng.uniform(*(PAPER_ROUGHNESS if paper else bounds))
                 for name, bounds in ROUGHNESS_RANGES.items()}
        roughness = drawn[self.roughness] if isinstance(self.roughness, str) else self.roughness
        return Material(np.array([*rgb, alpha]), self.metallic, roughness, self.specular)


PAPER_FILTER_IOR = 1.0 + 1e-4
"""The index of refraction of the paper's Transparent BSDF as we draw it (``paper_occluder_materials``):
the least above 1, so that the renderer takes its refraction path (``render.mirror``), which shows the
painting behind through the body undeviated and filtered by its colour, rather than blending the
lit body over it."""

_TRANSPARENT = SimpleMaterial(alpha=(0.2, 0.7), metallic=0.0, roughness="transparent", specular=0.5)


def _transparent(rng: np.random.Generator, config: SidarConfig) -> Material:
    """Lit and blended over what lies behind (alpha 0.2-0.7); with ``paper_occluder_materials``, from
    the same draws, the paper's Transparent BSDF: no shading of its own, a pure filter of colour ``c``
    (:func:`_colour`) at both of the body's surfaces, so the painting is seen through ``c ** 2``
    (alpha 0: only the Fresnel rise of quirk 5 at grazing views shows the body)."""
    material = _TRANSPARENT(rng, config)
    if not config.paper_occluder_materials:
        return material
    return Material(np.array([*np.square(material.base_color[:3]), 0.0]), 0.0, material.roughness, 0.0,
                    ior=PAPER_FILTER_IOR)


def _glass(rng: np.random.Generator, config: SidarConfig) -> Material:
    """Nearly clear (alpha 0.05-0.25) with a tint of saturation ``glass_saturation`` (which also colours
    the painting seen through it), a sharp clear-coat highlight, an index of refraction in [1, 2] (the
    paper's glass and refraction materials) and an opaque shadow if ``glass_shadows_opaque``. With
    ``paper_occluder_materials`` the tint is the paper's instead: its Glass BSDF colour ``c``
    (:func:`_colour`, uniform per linear channel) filters the light at both of the body's surfaces, so
    the painting behind is seen through ``c ** 2``."""
    if config.paper_occluder_materials:
        rgb = tuple(np.square(_colour(rng, config)))
    else:
        rgb = colorsys.hsv_to_rgb(rng.uniform(), rng.uniform(*config.glass_saturation), 1.0)
    alpha, roughness, coat_roughness = rng.uniform(0.05, 0.25), rng.uniform(0.02, 0.1), rng.uniform(0.02, 0.08)
    return Material(np.array([*rgb, alpha]), 0.0, roughness, 0.5, 1.0, coat_roughness, ior=rng.uniform(1.0, 2.0),
                    opaque_shadow=config.glass_shadows_opaque)


def _principled(rng: np.random.Generator, config: SidarConfig) -> Material:
    """Every factor random: colour, metallic, roughness, specular, coat and its roughness (0.03-0.3);
    with ``paper_occluder_materials`` the paper's Principled BSDF: roughness in :data:`PAPER_ROUGHNESS`,
    coat roughness and transmission in [0, 1] too."""
    rgb = _colour(rng, config)
    metallic, roughness, specular, coat = rng.uniform(size=4)
    if not config.paper_occluder_materials:
        return Material(np.array([*rgb, 1.0]), metallic, roughness, specular, coat, rng.uniform(0.03, 0.3))
    roughness = PAPER_ROUGHNESS[0] + roughness * (PAPER_ROUGHNESS[1] - PAPER_ROUGHNESS[0])
    coat_roughness, transmission = rng.uniform(size=2)
    return Material(np.array([*rgb, 1.0]), metallic, roughness, specular, coat, coat_roughness, transmission)


MATERIAL_KINDS: dict[str, Callable[[np.random.Generator, SidarConfig], Material]] = {
    "diffuse": SimpleMaterial(alpha=1.0, metallic=0.0, roughness=1.0, specular=0.0),  # Lambertian
    "glossy": SimpleMaterial(alpha=1.0, metallic=0.0, roughness="glossy", specular=1.0),  # a sharp highlight
    "metallic": SimpleMaterial(alpha=1.0, metallic=1.0, roughness="metallic", specular=0.5),  # tinted metal
    "transparent": _transparent,
    "glass": _glass,
    "principled": _principled,
}
"""``SidarConfig.occluder_materials`` name -> ``(rng, config) -> Material``. Transparent and glass
materials also get more opaque towards grazing angles (``render.programs``, quirk 5)."""


# --------------------------------------------------------------------------- occluder shapes


PAPER_TORUS_SCALE = np.array([1.25, 1.25, 0.25 / 0.3]) / 7
"""Per-axis scale of the unit torus (outer radius 1, tube 0.3 thick along z) that gives it the size of
the paper's torus, Blender's default one, never scaled (major radius 1, minor 0.25 Blender units;
``SidarConfig.paper_torus``): the same outer radius 1.25 / 7 and half-thickness 0.25 / 7 painting
units. Its tube is wider in the plane (0.3 of the outer radius against the paper's 0.2)."""


@dataclass(frozen=True)
class Shape:
    """What the scene knows of an occluder shape (its meshes are ``render.meshes``').

    Attributes:
        variants: how many fixed meshes it comes in (random hulls and prisms: 8; else 1).
        paper_scale: the fixed scale it takes with ``SidarConfig.paper_torus`` (the torus), else None.
        box: ``(3,)`` half-extents of a box about the origin holding every mesh of the shape (unit
            primitive frame; every level and variant).
        disc: radius in the xy plane, and ``box[2]`` the half-height, of a cylinder about z holding them.
        ball: radius of a ball about the origin holding them. ``tests/scene/test_scene.py`` checks
            all three against the meshes' vertices (each region is convex, so a mesh's faces are
            inside too).
    """

    variants: int = 1
    paper_scale: np.ndarray | None = None
    box: tuple[float, float, float] = (1.0, 1.0, 1.0)
    disc: float = 1.0
    ball: float = math.sqrt(2.0)

    def radius(self, scale: np.ndarray) -> float:
        """Radius of a ball about the origin holding the shape scaled by ``scale`` ``(3,)`` (before
        its rotation, which the ball ignores): the least of its box's, cylinder's and ball's, scaled;
        at most ``|scale|``, the unit box's."""
        sx, sy, sz = (float(v) for v in scale)
        return min(math.hypot(sx * self.box[0], sy * self.box[1], sz * self.box[2]),
                   math.hypot(max(sx, sy) * self.disc, sz * self.box[2]), max(sx, sy, sz) * self.ball)


SHAPES: dict[str, Shape] = {
    "sphere": Shape(ball=1.0), "cube": Shape(disc=math.sqrt(2.0), ball=math.sqrt(3.0)), "cylinder": Shape(),
    "cone": Shape(), "torus": Shape(paper_scale=PAPER_TORUS_SCALE, box=(1.0, 1.0, 0.3), ball=1.0),
    "capsule": Shape(box=(0.5, 0.5, 1.0), disc=0.5, ball=1.0),
    "icosahedron": Shape(box=(0.851, 0.851, 0.851), ball=1.0),
    "hull": Shape(variants=8, ball=1.0), "prism": Shape(variants=8),
}
"""``SidarConfig.occluder_shapes`` name -> its scene facts."""


def occluder_radius(occluder: Occluder) -> float:
    """Radius of a ball about ``occluder.position`` holding the occluder (painting units):
    ``SHAPES[occluder.shape].radius(occluder.scale)``, e.g. the largest scale of a sphere where
    ``|scale|`` would be about 1.7 times that."""
    return SHAPES[occluder.shape].radius(occluder.scale)
