"""A SIDAR scene as plain data, and the pure functions that sample one.

Nothing here knows OpenGL: a sequence can be sampled, printed, compared and tested without
a renderer. All positions are world coordinates in painting units (see ``sidar_torch.config``);
angles are radians; colours are linear RGB in [0, 1].

Every light is aimed at the painting's centre and is made of one or more *emitters*, each
rendered as a spot light: a spot light is one emitter; a point light is one emitter whose
inner cone covers the whole painting (on the painting this is exactly a point light, since a
point light is a spot light with an unbounded cone); an area light is several emitters
spread over a square facing the painting, whose shadows overlap into a penumbra.
"""

from __future__ import annotations

import colorsys
import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from . import geometry
from .config import SidarConfig

__all__ = [
    "Camera",
    "Light",
    "Material",
    "Occluder",
    "SceneSequence",
    "ViewScene",
    "sample_sequence",
    "spread_beam",
]

MAX_EMITTER_CONE = 1.0
"""Largest outer half-angle (rad) of an emitter's cone: wider shadow frusta give shadow acne."""

CONE_MARGIN = math.radians(1.0)
"""Angle by which a painting-covering cone exceeds the painting's farthest corner."""


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
        kind: ``"spot"``, ``"point"`` or ``"area"``.
        emitters: ``(S, 3)`` emitter positions.
        color: ``(3,)`` linear RGB.
        intensity: each emitter's intensity, such that an emitter at distance ``d`` whose ray
            meets the painting at incidence angle ``theta`` gives it irradiance
            ``intensity * cos(theta) / d**2`` inside its inner cone.
        inner_cone, outer_cone: half-angles (rad); the light falls off quadratically between them.
    """

    kind: str
    emitters: np.ndarray
    color: np.ndarray
    intensity: float
    inner_cone: float
    outer_cone: float


@dataclass(frozen=True, eq=False)
class Occluder(_Plain):
    """A unit primitive (``shape``, within the box ``|x_k| <= 1``; ``variant`` picks one of the
    :data:`SHAPE_VARIANTS` fixed meshes of a ``hull`` or ``prism``, else 0) scaled by ``scale (3,)``, rotated by
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

    How it is drawn (shadows, occluders seen by the cameras, masks) is the renderer's business
    (``sidar_torch.render.RenderSettings``), not the scene's.
    """

    image_size: tuple[int, int]
    views: tuple[ViewScene, ...]

    def cameras(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Stacked ``K (V, 3, 3)``, ``R (V, 3, 3)``, ``t (V, 3)`` float64."""
        cams = [v.camera for v in self.views]
        return np.stack([c.K for c in cams]), np.stack([c.R for c in cams]), np.stack([c.t for c in cams])


def sample_sequence(config: SidarConfig, rng: np.random.Generator) -> SceneSequence:
    """Draw one sample's scenes from ``config`` with ``rng`` (a pure function of the rng's state).

    Cameras are drawn first (view 0 the reference, then views 1..V-1), then each view's lights,
    occluders and materials, or one set reused by every view when ``scene_per_view`` is false.
    """
    size = config.image_size
    cameras = _sample_cameras(config, rng)
    content = None
    views = []
    for camera in cameras:
        if content is None or config.scene_per_view:
            content = _sample_content(config, rng, size, cameras)
        views.append(ViewScene(camera, *content))
    return SceneSequence(size, tuple(views))


CAMERA_ATTEMPTS = 1000
"""Draws per view before the sampler gives up on ``min_coverage`` / ``min_overlap``."""


def _sample_cameras(config: SidarConfig, rng: np.random.Generator) -> list[Camera]:
    size = config.image_size
    reference = Camera(*geometry.reference_camera(size, rng.uniform(*config.camera_height)))
    if config.aligned:
        return [reference] * config.n_views
    cameras = [reference]
    for _ in range(config.n_views - 1):
        for _ in range(CAMERA_ATTEMPTS):
            position = _camera_position(config, rng)
            K = geometry.intrinsics_from_fov(rng.uniform(*config.fov_deg), size)
            camera = Camera(K, *geometry.look_at(position))
            if _meets_guarantees(camera, cameras, config):
                break
        else:
            raise ValueError(
                f"config fields 'min_coverage' ({config.min_coverage}) and 'min_overlap' "
                f"({config.min_overlap}): no camera met them in {CAMERA_ATTEMPTS} draws from "
                f"camera_xy={config.camera_xy}, camera_height={config.camera_height}, fov_deg="
                f"{config.fov_deg}, max_tilt_deg={config.max_tilt_deg}; lower them or narrow the camera ranges")
        cameras.append(camera)
    return cameras


def _meets_guarantees(camera: Camera, previous: list[Camera], config: SidarConfig) -> bool:
    """Whether the painting covers at least ``min_coverage`` of the camera's image, and each of the
    camera and every ``previous`` one sees at least ``min_overlap`` of the other's painting pixels."""
    if config.min_coverage == 0 and config.min_overlap == 0:
        return True
    size = config.image_size
    seen = geometry.painting_pixel_area(camera.K, camera.R, camera.t, size)
    if seen < config.min_coverage * size[0] * size[1] or seen == 0:
        return False
    if config.min_overlap == 0:
        return True
    mine = geometry.visible_halfplanes(camera.K, camera.R, camera.t, size)
    for other in previous:
        theirs = geometry.visible_halfplanes(other.K, other.R, other.t, size)
        both = geometry.painting_pixel_area(camera.K, camera.R, camera.t, size, (theirs,))
        other_seen = geometry.painting_pixel_area(other.K, other.R, other.t, size)
        other_both = geometry.painting_pixel_area(other.K, other.R, other.t, size, (mine,))
        if both < config.min_overlap * seen or other_both < config.min_overlap * other_seen:
            return False
    return True


def _camera_position(config: SidarConfig, rng: np.random.Generator, attempts: int = 64) -> np.ndarray:
    """A camera centre drawn uniformly from the box ``|x|, |y| <= camera_xy`` (z from
    ``camera_height``) restricted to tilts of at most ``max_tilt_deg`` (90: no restriction; the config
    refuses a limit the box cannot reach, so the field always shapes the draw it names).

    Rejection from the square ``|x|, |y| <= min(camera_xy, r)``, ``r`` the tilt disc's radius,
    accepts with probability at least pi/4; after ``attempts`` failures (probability below
    1e-40) the camera looks straight down.
    """
    z = rng.uniform(*config.camera_height)
    radius = z * math.tan(math.radians(config.max_tilt_deg))
    half = min(config.camera_xy, radius)
    for _ in range(attempts):
        x, y = rng.uniform(-half, half, size=2)
        if x * x + y * y <= radius * radius:
            return np.array([x, y, z])
    return np.array([0.0, 0.0, z])


def _sample_content(config: SidarConfig, rng: np.random.Generator, size: tuple[int, int], cameras: list[Camera]):
    n_lights = rng.integers(config.n_lights[0], config.n_lights[1] + 1)
    lights = tuple(_sample_light(config, rng, size) for _ in range(n_lights))
    n_occluders = rng.integers(config.n_occluders[0], config.n_occluders[1] + 1)
    centres = np.stack([camera.position for camera in cameras])
    occluders = tuple(o for o in (_sample_occluder(config, rng, centres) for _ in range(n_occluders)) if o is not None)
    return lights, occluders, _plane_material(config, rng), rng.uniform(*config.ambient)


def _plane_material(config: SidarConfig, rng: np.random.Generator) -> Material:
    """The painting's material: white base (the texture gives its colour), the rest from the
    ``plane_*`` ranges, or purely diffuse when ``plane_diffuse`` is set (no draws then).
    Transmission is drawn only when ``plane_transmission`` is not ``(0, 0)``, so configs without
    it draw the same numbers as before the field existed."""
    if config.plane_diffuse:
        return Material(np.ones(4), 0.0, 1.0, specular=0.0)
    metallic, roughness, specular, coat, coat_roughness = (rng.uniform(*r) for r in (
        config.plane_metallic, config.plane_roughness, config.plane_specular, config.plane_coat,
        config.plane_coat_roughness))
    transmission = rng.uniform(*config.plane_transmission) if any(config.plane_transmission) else 0.0
    return Material(np.ones(4), metallic, roughness, specular, coat, coat_roughness, transmission)


def _sample_light(config: SidarConfig, rng: np.random.Generator, size: tuple[int, int]) -> Light:
    kind = config.light_types[rng.integers(len(config.light_types))]
    xy = rng.uniform(-config.light_xy, config.light_xy, size=2)
    position = np.array([xy[0], xy[1], rng.uniform(*config.light_height)])
    color = np.array(colorsys.hsv_to_rgb(rng.uniform(), rng.uniform(0, config.light_saturation_max), 1.0))
    irradiance = rng.uniform(*{"spot": config.spot_irradiance, "point": config.light_irradiance,
                               "area": config.area_irradiance}[kind])
    if kind == "spot":
        outer = min(math.radians(rng.uniform(*config.spot_cone_deg)) / 2, MAX_EMITTER_CONE)
        inner = outer * (1.0 - rng.uniform())
        emitters = position[None]
    else:
        n = config.area_light_samples if kind == "area" else 1
        offsets = rng.uniform(-0.5, 0.5, size=(n, 2)) * config.area_light_size if kind == "area" else np.zeros((1, 2))
        position, emitters = _covering_emitters(position, offsets, size)
        inner = max(_cover_angle(e, size) for e in emitters)
        outer = inner + CONE_MARGIN
        if kind == "area" and config.area_spread_deg != (180.0, 180.0):
            inner, outer, irradiance = spread_beam(rng.uniform(*config.area_spread_deg), irradiance)
        # Emitters share the light's intensity so the total irradiance is the sampled one.
        irradiance /= n
    distance = np.linalg.norm(position)
    intensity = irradiance * distance**2 / (position[2] / distance)
    return Light(kind, emitters, color, float(intensity), float(inner), float(outer))


def spread_beam(spread_deg: float, irradiance: float) -> tuple[float, float, float]:
    """Inner and outer cone (rad) and centre irradiance of an area light narrowed by Blender's
    ``spread`` (full angle, degrees) whose unnarrowed centre irradiance is ``irradiance``.

    Cycles keeps a spread light's power and concentrates it within ``a = spread / 2`` of its axis,
    with a profile falling linearly in ``tan`` to 0 at ``a`` (peak ``tan a / (tan a - a)`` times the
    unnarrowed light). Here the beam is a spot with no inner cone (the renderer's quadratic falloff
    ``((cos t - cos a) / (1 - cos a))**2``), the same power: the centre irradiance times
    ``3 / (2 (1 - cos a))`` (within 10 % of Cycles' peak for spreads of 10-90 degrees). ``a`` is capped
    at :data:`MAX_EMITTER_CONE`.
    """
    outer = min(math.radians(spread_deg) / 2, MAX_EMITTER_CONE)
    return 0.0, outer, irradiance * 3.0 / (2.0 * (1.0 - math.cos(outer)))


def _cover_angle(emitter: np.ndarray, size: tuple[int, int]) -> float:
    """Largest angle (rad) between the emitter's axis (towards the centre) and a painting corner,
    plus :data:`CONE_MARGIN`."""
    axis = -emitter / np.linalg.norm(emitter)
    rays = geometry.plane_corners(size) - emitter
    cos = rays @ axis / np.linalg.norm(rays, axis=1)
    return float(np.arccos(np.clip(cos, -1.0, 1.0)).max()) + CONE_MARGIN


def _covering_emitters(position: np.ndarray, offsets: np.ndarray, size: tuple[int, int]):
    """Emitters at ``offsets (S, 2)`` on a square centred at ``position`` and facing the origin,
    moved away from the centre along its ray until every emitter's painting-covering cone fits
    within :data:`MAX_EMITTER_CONE` (no move if they already do).

    Returns:
        the (possibly moved) centre ``(3,)`` and the emitters ``(S, 3)``.
    """
    while True:
        u, v, _ = geometry.look_at(position)[0]  # the square's axes: a camera's x and y there
        emitters = position + offsets[:, :1] * u + offsets[:, 1:] * v
        if max(_cover_angle(e, size) for e in emitters) <= MAX_EMITTER_CONE - CONE_MARGIN:
            return position, emitters
        position = position * 1.25


HULL_VARIANTS = 8
"""Distinct ``hull`` primitives an occluder can be (see ``render.meshes``)."""

PRISM_VARIANTS = 8
"""Distinct ``prism`` (extruded polygon) primitives an occluder can be (see ``render.meshes``)."""

SHAPE_VARIANTS = {"hull": HULL_VARIANTS, "prism": PRISM_VARIANTS}
"""Shapes that come in several fixed variants, and how many; every other shape has one (variant 0)."""

PAPER_TORUS_SCALE = np.array([1.25, 1.25, 0.25 / 0.3]) / 7
"""Per-axis scale of the unit torus (outer radius 1, tube 0.3 thick along z) that gives it the size of
the paper's torus, Blender's default one, never scaled (major radius 1, minor 0.25 Blender units;
``SidarConfig.paper_torus``): the same outer radius 1.25 / 7 and half-thickness 0.25 / 7 painting
units. Its tube is wider in the plane (0.3 of the outer radius against the paper's 0.2)."""

OCCLUDER_ATTEMPTS = 100
"""Placements tried for an occluder before it is left out of the view."""

CAMERA_CLEARANCE = 0.01
"""Least gap (painting units) between a camera and an occluder's bounding sphere: far more than
the renderer's near plane (under 1e-3), so no occluder is cut open by it."""


def _sample_occluder(config: SidarConfig, rng: np.random.Generator, cameras: np.ndarray) -> Occluder | None:
    """An occluder clear of every camera centre ``cameras (V, 3)``, or ``None`` when
    :data:`OCCLUDER_ATTEMPTS` placements all enclose a camera.

    A camera inside an occluder would not see it (back faces are culled) while its shadow falls
    on the view, and the mask would miss it.
    """
    shape = config.occluder_shapes[rng.integers(len(config.occluder_shapes))]
    rotation = _random_rotation(rng)
    fixed = shape == "torus" and config.paper_torus
    scale = PAPER_TORUS_SCALE if fixed else rng.uniform(*config.occluder_size, size=3)
    variant = int(rng.integers(SHAPE_VARIANTS[shape])) if shape in SHAPE_VARIANTS else 0
    kind = config.occluder_materials[rng.integers(len(config.occluder_materials))]
    material = _occluder_material(kind, rng, opaque_glass_shadow=config.glass_shadows_opaque)
    radius = float(np.linalg.norm(scale))  # the unit primitive lies within the box |x_k| <= 1
    for _ in range(OCCLUDER_ATTEMPTS):
        xy = rng.uniform(-config.occluder_xy, config.occluder_xy, size=2)
        position = np.array([xy[0], xy[1], rng.uniform(*config.occluder_height)])
        if np.linalg.norm(cameras - position, axis=1).min() > radius + CAMERA_CLEARANCE:
            return Occluder(shape, position, rotation, scale, material, variant)
    return None


def _random_rotation(rng: np.random.Generator) -> np.ndarray:
    """A rotation matrix ``(3, 3)`` uniform over SO(3) (normalised Gaussian quaternion)."""
    w, x, y, z = (q := rng.normal(size=4)) / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def _occluder_material(kind: str, rng: np.random.Generator, opaque_glass_shadow: bool = False) -> Material:
    """An occluder material of one of ``config.OCCLUDER_MATERIALS``:

    * ``diffuse``: Lambertian (no specular); ``glossy``: dielectric with a sharp highlight;
      ``metallic``: metal tinted by its colour;
    * ``transparent``: alpha 0.2-0.7, tinted; ``glass``: nearly clear (alpha 0.05-0.25, pale
      tint) with a sharp clear-coat highlight, an index of refraction in [1, 2] (the paper's glass
      and refraction materials) and an opaque shadow if ``opaque_glass_shadow``; both get more
      opaque towards grazing angles;
    * ``principled``: every factor random (base colour, metallic, roughness, specular, coat).
    """
    if kind == "glass":
        rgb = colorsys.hsv_to_rgb(rng.uniform(), rng.uniform(0.0, 0.3), 1.0)
        alpha, roughness, coat_roughness = rng.uniform(0.05, 0.25), rng.uniform(0.02, 0.1), rng.uniform(0.02, 0.08)
        return Material(np.array([*rgb, alpha]), 0.0, roughness, 0.5, 1.0, coat_roughness, ior=rng.uniform(1.0, 2.0),
                        opaque_shadow=opaque_glass_shadow)
    rgb = colorsys.hsv_to_rgb(rng.uniform(), rng.uniform(), rng.uniform(0.2, 1.0))
    if kind == "principled":
        metallic, roughness, specular, coat = rng.uniform(size=4)
        return Material(np.array([*rgb, 1.0]), metallic, roughness, specular, coat, rng.uniform(0.03, 0.3))
    alpha = rng.uniform(0.2, 0.7) if kind == "transparent" else 1.0
    metallic = 1.0 if kind == "metallic" else 0.0
    roughness = {"diffuse": 1.0, "glossy": rng.uniform(0.05, 0.3),
                 "metallic": rng.uniform(0.05, 0.4), "transparent": rng.uniform(0.05, 0.5)}[kind]
    specular = {"diffuse": 0.0, "glossy": 1.0}.get(kind, 0.5)
    return Material(np.array([*rgb, alpha]), metallic, roughness, specular)
