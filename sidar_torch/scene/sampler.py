"""Sampling a SIDAR scene: pure functions of a ``SidarConfig`` and a numpy ``Generator``.

:func:`sample_sequence` draws the cameras first (view 0 the reference, then views 1..V-1), then each
view's lights, occluders and materials (the kinds' own draws are :mod:`.kinds`' rows), so a
sequence is a pure function of the generator's state.
"""

from __future__ import annotations

import colorsys
import math

import numpy as np

from .. import geometry
from ..choices.lenses import LENS_MODELS, NO_LENS, scaled_lens
from ..config import SidarConfig
from .description import Camera, Light, Material, Occluder, SceneSequence, ViewScene
from .kinds import LIGHT_KINDS, MATERIAL_KINDS, SHAPES

__all__ = ["CAMERA_ATTEMPTS", "CAMERA_CLEARANCE", "OCCLUDER_ATTEMPTS", "sample_sequence"]


def sample_sequence(config: SidarConfig, rng: np.random.Generator) -> SceneSequence:
    """Draw one sample's scenes from ``config`` with ``rng`` (a pure function of the rng's state).

    Cameras are drawn first (view 0 the reference, then views 1..V-1), then each view's lights,
    occluders and materials, or one set reused by every view when ``scene_per_view`` is false; with a
    ``lens_model``, each view's lens last, from a generator of its own (:func:`_sample_lenses`).
    """
    size = config.image_size
    cameras = _sample_cameras(config, rng)
    centres = np.stack([camera.position for camera in cameras])  # (V, 3): occluders keep clear of them
    content = None
    views = []
    for camera in cameras:
        if content is None or config.scene_per_view:
            content = _sample_content(config, rng, size, centres)
        views.append(ViewScene(camera, *content))
    if config.lens_model == NO_LENS:
        return SceneSequence(size, tuple(views))
    return SceneSequence(size, tuple(views), config.lens_model, _sample_lenses(config, rng, cameras))


def _sample_lenses(config: SidarConfig, rng: np.random.Generator, cameras: list[Camera]) -> np.ndarray:
    """Each view's lens ``(V, 5)`` (:func:`sidar_torch.choices.lenses.scaled_lens` of coefficients drawn from
    the config's ranges at the image's corner), drawn from ``Generator(rng.bit_generator.jumped())``: a
    stream 2**127 steps ahead of ``rng``'s, a pure function of its state that leaves it untouched, so
    the lens changes no draw of the scene or of what ``rng`` draws next (the view effects)."""
    if not hasattr(rng.bit_generator, "jumped"):
        raise ValueError(f"rng: lens_model {config.lens_model!r} draws from a jumped copy of the generator, which "
                         f"needs a bit generator with jumped() (numpy.random.default_rng's PCG64), got "
                         f"{type(rng.bit_generator).__name__}")
    lens_rng = np.random.Generator(rng.bit_generator.jumped())
    fields = LENS_MODELS[config.lens_model].fields
    lenses = []
    for camera in cameras:
        corner = [lens_rng.uniform(*getattr(config, f)) if f is not None else 0.0 for f in fields]
        lenses.append(scaled_lens(config.lens_model, np.array(corner), camera.K, config.image_size))
    return np.stack(lenses)


CAMERA_ATTEMPTS = 1000
"""Draws per view before the sampler gives up on ``min_coverage`` / ``min_overlap``."""


def _sample_cameras(config: SidarConfig, rng: np.random.Generator) -> list[Camera]:
    size = config.image_size
    heights = config.reference_height if config.reference_height != (0.0, 0.0) else config.camera_height
    reference = Camera(*geometry.reference_camera(size, rng.uniform(*heights)))
    if config.aligned:
        return [reference] * config.n_views
    cameras = [reference]
    for _ in range(config.n_views - 1):
        for _ in range(CAMERA_ATTEMPTS):
            position = _camera_position(config, rng)
            K = geometry.intrinsics_from_fov(_fov(config, rng), size)
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


def _fov(config: SidarConfig, rng: np.random.Generator) -> float:
    """A view's field of view (degrees) from one draw: uniform in ``fov_deg``, or, with ``focal_uniform``,
    the angle of a focal length uniform between those of its ends."""
    if not config.focal_uniform:
        return rng.uniform(*config.fov_deg)
    longest, shortest = (1.0 / math.tan(math.radians(a) / 2) for a in config.fov_deg)  # focal / half width
    return math.degrees(2.0 * math.atan(1.0 / rng.uniform(shortest, longest)))


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


def _sample_content(config: SidarConfig, rng: np.random.Generator, size: tuple[int, int], centres: np.ndarray):
    """One view's lights, occluders (clear of the camera centres ``centres (V, 3)``), painting material
    and ambient level."""
    n_lights = rng.integers(config.n_lights[0], config.n_lights[1] + 1)
    lights = tuple(_sample_light(config, rng, size) for _ in range(n_lights))
    n_occluders = rng.integers(config.n_occluders[0], config.n_occluders[1] + 1)
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
    """A light of a kind drawn from ``light_types``: position, colour and irradiance at the painting's
    centre drawn here (:func:`_centre_irradiance`), its emitters and cones by its
    :data:`~.kinds.LIGHT_KINDS` row."""
    name = config.light_types[rng.integers(len(config.light_types))]
    kind = LIGHT_KINDS[name]
    xy = rng.uniform(-config.light_xy, config.light_xy, size=2)
    position = np.array([xy[0], xy[1], rng.uniform(*config.light_height)])
    color = np.array(colorsys.hsv_to_rgb(rng.uniform(), rng.uniform(0, config.light_saturation_max), 1.0))
    beam = kind.beam(config, rng, position, _centre_irradiance(config, rng, kind.irradiance, kind.intensity, position),
                     size)
    distance = np.linalg.norm(beam.position)
    intensity = beam.irradiance * distance**2 / (beam.position[2] / distance)
    return Light(name, beam.emitters, color, float(intensity), float(beam.inner_cone), float(beam.outer_cone),
                 beam.smooth_falloff)


def _centre_irradiance(config: SidarConfig, rng: np.random.Generator, irradiance: str, intensity: str,
                       position: np.ndarray) -> float:
    """The irradiance a light at ``position (3,)`` gives the painting's centre, from one draw: from the
    config's range field ``irradiance``, or, unless it is ``(0, 0)``, from the intensity range field
    ``intensity`` as ``I cos / d**2`` (``d = |position|``, ``cos = z / d``: the paper's generator draws
    a light's power, so a far light is a dim one). The beam keeps this irradiance at the centre even
    if it moves the light back (:func:`~.kinds._covering_emitters`, never within the paper's box)."""
    drawn = getattr(config, intensity)
    if drawn == (0.0, 0.0):
        return rng.uniform(*getattr(config, irradiance))
    return rng.uniform(*drawn) * float(position[2]) / float(np.linalg.norm(position)) ** 3


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
    facts = SHAPES[shape]
    rotation = (geometry.euler_rotation(rng.uniform(0.0, 2.0 * np.pi, size=3)) if config.paper_rotation
                else _random_rotation(rng))
    fixed = facts.paper_scale is not None and config.paper_torus
    scale = facts.paper_scale if fixed else rng.uniform(*config.occluder_size, size=3)
    variant = int(rng.integers(facts.variants)) if facts.variants > 1 else 0
    kind = config.occluder_materials[rng.integers(len(config.occluder_materials))]
    material = MATERIAL_KINDS[kind](rng, config)
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
