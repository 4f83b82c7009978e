"""Configuration: every range and switch of a SIDAR scene, YAML presets, validation.

Units. Lengths are in *painting units*: the painting's shorter side is 1 (the paper's
Blender scenes use 7 Blender units for it, so its ranges are divided by 7 here). Angles
are in degrees. Light strength is the irradiance a light gives the painting's centre,
in the renderer's linear units, where a white diffuse painting saturates at about 3.3
(see ``sidar_torch.render``).

A range is a pair ``(low, high)`` with ``low <= high``; values are drawn uniformly from
it. Presets are the YAML files in ``configs/`` (``load_config("misaligned")``); a YAML
file may name a ``base`` preset and override some of its fields.
"""

from __future__ import annotations

import dataclasses
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

import yaml

from .render_choices import MAX_SHADOWED_LIGHTS, SHADOW_FILTERS, SHADOW_FRUSTA, TEXTURE_FILTERS

__all__ = [
    "BACKGROUNDS",
    "LIGHT_TYPES",
    "OCCLUDER_MATERIALS",
    "MESH_DETAILS",
    "OCCLUDER_SHAPES",
    "ON_BAD_IMAGE",
    "SHADOW_FILTERS",
    "SHADOW_FRUSTA",
    "TEXTURE_FILTERS",
    "SidarConfig",
    "available_presets",
    "load_config",
]

CONFIG_DIR = Path(__file__).resolve().parent.parent / "configs"
"""Folder of the YAML presets (``configs/`` at the top of the repository)."""

LIGHT_TYPES = ("spot", "point", "area")
OCCLUDER_SHAPES = ("sphere", "cube", "cylinder", "cone", "torus", "capsule", "icosahedron", "hull", "prism")
OCCLUDER_MATERIALS = ("diffuse", "glossy", "metallic", "transparent", "glass", "principled")
ON_BAD_IMAGE = ("raise", "skip")
BACKGROUNDS = ("black", "view", "sequence")
MESH_DETAILS = ("fixed", "auto")

Range = tuple[float, float]
IntRange = tuple[int, int]


@dataclass(frozen=True)
class SidarConfig:
    """Every parameter of the scene sampler and renderer (frozen; see module docstring for units).

    Output
        image_size: ``(H, W)`` of every view, mask and label, in pixels.
        n_views: number of views ``V`` per sample; view 0 is the fronto-parallel reference.

    Cameras
        aligned: every view through the reference camera (all homographies identity).
        camera_xy: half-width of the square in which camera x and y are drawn.
        camera_height: range of camera z (distance above the painting's plane).
        fov_deg: range of the field of view across the longer image side, for views 1..V-1.
        max_tilt_deg: largest angle between a camera's axis and the painting's normal.
        min_coverage: least fraction of each view's pixels that see the painting (cameras are
            redrawn until it holds; see ``sidar_torch.scene``).
        min_overlap: least fraction of the painting pixels of any view ``i`` that another view
            ``j`` also sees (every ordered pair; cameras are redrawn until it holds).

    Scene content (drawn afresh for every view unless ``scene_per_view`` is false)
        n_lights: range of the number of lights.
        light_types: light kinds to draw from (``spot``, ``point``, ``area``).
        light_xy, light_height: light position box, like the cameras'.
        light_irradiance, spot_irradiance, area_irradiance: ranges of a point, spot and area
            light's irradiance at the painting's centre (an area light's summed over its emitters).
            The defaults keep the paper's power ratios (point 1-3.5 kW, spot 1-10 kW, area
            1-2 kW radiating into a half-space, i.e. 4-8 kW point-equivalent) at a scale chosen
            so that the fraction of blown-out painting pixels matches the paper's renders
            (``scripts/exposure.py``).
        light_saturation_max: colour is HSV(U(0, 1), U(0, this), 1).
        spot_cone_deg: range of a spot light's full cone angle.
        area_light_size: side of a square area light.
        area_light_samples: jittered shadow-casting samples an area light is made of.
        ambient: range of the ambient light level (linear, 1 reproduces the texture).
        n_occluders: range of the number of occluding objects.
        occluder_shapes, occluder_materials: kinds to draw from.
        occluder_xy, occluder_height: box of occluder centres.
        occluder_size: range of an occluder's half-extent along each of its axes.
        occluders_visible: false makes occluders invisible to cameras; they still cast shadows.
        mask_min_opacity: occluders whose material opacity (alpha) is below this are left out of
            the masks: the painting seen through them counts as visible. 0 (the paper's choice)
            masks every occluder, however transparent.
        opacity_output: also hand out ``opacities``, a soft mask per view: the fraction of the
            painting hidden at each pixel (1 off the painting and behind opaque occluders, 0 where
            it is seen unobstructed, ``1 - prod(1 - a_k)`` through transparent occluders of
            opacity ``a_k``), whatever ``mask_min_opacity`` is. Costs one unlit draw per view.
        shadows: whether lights cast shadows.
        plane_roughness, plane_metallic: ranges of the painting's material.
        plane_specular: range of the painting's specular level (dielectric reflectance at normal
            incidence ``0.08 * level``, Blender's convention: 0.5 is 4 %).
        plane_coat, plane_coat_roughness: ranges of the weight and roughness of a clear coat on
            the painting (a second, sharper specular lobe with 4 % reflectance).
        plane_diffuse: a purely diffuse painting (metallic 0, roughness 1, no specular, no coat),
            overriding the other ``plane_*`` ranges.
        scene_per_view: draw new lights, occluders and painting material for every view.

    Rendering
        shadow_map_size: side of each shadow map in texels (power of two).
        shadow_filter: how a shadow-map lookup is filtered: ``"tent"``, a 3 x 3 tent-weighted
            percentage-closer filter from 4 bilinear depth-compare taps, or ``"bilinear"``, a 2 x 2
            filter from one tap (a quarter of the texture reads: shadow edges one texel sharper).

    View effects (beyond the paper; each off by default. Per-pixel effects on the rendered views
    only, drawn after the scene so switching one on changes no scene, mask, label or homography;
    see ``sidar_torch.artifacts``)
        background: what the views show where nothing was drawn: ``"black"`` (the paper's),
            ``"view"`` (a random colour per view) or ``"sequence"`` (one random colour per sample).
        background_level: range each 8-bit sRGB channel of a background colour is drawn from, as
            a fraction of 255.
        exposure_jitter: scale each view's linear intensity by ``2 ** stops`` and raise it to a
            power ``gamma`` (drawn per view).
        exposure_stops: range of the exposure change, in stops (EV).
        gamma: range of the exponent applied to a view's linear intensity (after exposure and noise).
        sensor_noise: add Gaussian read noise and signal-dependent shot noise in linear light.
        read_noise: range of a view's read-noise standard deviation (linear intensity, 1 is white).
        shot_noise: range of a view's shot-noise scale ``k``: variance ``k * x`` at linear
            intensity ``x`` (a Poisson count of ``x / k`` photons, times ``k``; Gaussian approximation).
        jpeg: compress each view as JPEG and decode it (Pillow, in memory, 4:2:0 chroma).
        jpeg_quality: range of a view's JPEG quality (Pillow's scale, 1-100).
        shadow_frustum: what a spot light's shadow map covers: ``"cone"`` (pyrender's frustum, 2 x
            outer cone + pi / 16 wide) or ``"fitted"`` (only what the cameras see of the painting and
            occluders, within the cone: the same map size gives finer shadows; the default, as the
            sweep found it closer to the reference at every map size for the same time).
        mesh_detail: ``"fixed"``: every curved occluder (sphere, cylinder, cone, torus, capsule) uses
            one mesh (icosphere 3, 48 sections); ``"auto"``: per view, the coarsest of 4 pooled levels
            whose silhouette and shadow stay within ``mesh_error_px`` of the true surface.
        mesh_error_px: the largest silhouette error, in pixels, ``mesh_detail`` "auto" allows (0: always
            the finest level).
        texture_filter: the painting texture's filter, ``"trilinear"`` (mipmapped) or ``"bilinear"``
            (full-size texture only; aliases where a view shrinks the painting).

    Input
        on_bad_image: what a painting source does with an unreadable image: ``"raise"`` (an
            error naming the file) or ``"skip"`` (a warning, and the next readable image).
    """

    image_size: tuple[int, int] = (384, 512)
    n_views: int = 6

    aligned: bool = False
    camera_xy: float = 5 / 7
    camera_height: Range = (5 / 7, 1.0)
    fov_deg: Range = (61.9, 100.4)
    max_tilt_deg: float = 60.0
    min_coverage: float = 0.0
    min_overlap: float = 0.0

    n_lights: IntRange = (2, 4)
    light_types: tuple[str, ...] = LIGHT_TYPES
    light_xy: float = 10 / 7
    light_height: Range = (10 / 7, 15 / 7)
    light_irradiance: Range = (0.5, 1.75)
    spot_irradiance: Range = (0.5, 5.0)
    area_irradiance: Range = (2.0, 4.0)
    light_saturation_max: float = 0.3
    spot_cone_deg: Range = (10.0, 90.0)
    area_light_size: float = 0.3
    area_light_samples: int = 4
    ambient: Range = (0.0, 0.02)

    n_occluders: IntRange = (0, 3)
    occluder_shapes: tuple[str, ...] = OCCLUDER_SHAPES
    occluder_materials: tuple[str, ...] = OCCLUDER_MATERIALS
    occluder_xy: float = 3 / 7
    occluder_height: Range = (1 / 7, 5 / 7)
    occluder_size: Range = (0.1 / 7, 1.1 / 7)
    occluders_visible: bool = True
    mask_min_opacity: float = 0.0
    opacity_output: bool = False
    shadows: bool = True

    plane_roughness: Range = (0.4, 1.0)
    plane_metallic: Range = (0.0, 0.2)
    plane_specular: Range = (0.0, 1.0)
    plane_coat: Range = (0.0, 1.0)
    plane_coat_roughness: Range = (0.03, 0.3)
    plane_diffuse: bool = False
    scene_per_view: bool = True

    shadow_map_size: int = 1024
    shadow_filter: str = "tent"

    background: str = "black"
    background_level: Range = (0.0, 1.0)
    exposure_jitter: bool = False
    exposure_stops: Range = (-1.0, 1.0)
    gamma: Range = (0.8, 1.25)
    sensor_noise: bool = False
    read_noise: Range = (0.0, 0.01)
    shot_noise: Range = (0.0, 0.002)
    jpeg: bool = False
    jpeg_quality: IntRange = (30, 95)
    shadow_frustum: str = "fitted"
    mesh_detail: str = "fixed"
    mesh_error_px: float = 0.25
    texture_filter: str = "trilinear"

    on_bad_image: str = "raise"

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            object.__setattr__(self, f.name, _coerce(f, getattr(self, f.name)))
        _validate(self)

    def replace(self, **overrides: Any) -> "SidarConfig":
        """Return a copy with some fields changed (validated like the constructor)."""
        _check_names(overrides, "override")
        return dataclasses.replace(self, **overrides)

    def to_dict(self) -> dict[str, Any]:
        """Plain-data view (lists for tuples), suitable for YAML or JSON."""
        return {k: list(v) if isinstance(v, tuple) else v for k, v in dataclasses.asdict(self).items()}


def _coerce(f: dataclasses.Field, value: Any) -> Any:
    """Turn YAML lists into tuples and ints into floats where the field's type asks for it."""
    kind = str(f.type)
    if kind.startswith(("Range", "IntRange", "tuple")):
        if isinstance(value, (str, bytes, set, frozenset, dict)) or not hasattr(value, "__iter__"):
            # Sets are refused: their order follows string hashing, which changes between processes.
            raise ValueError(f"config field {f.name!r}: expected a list or tuple, got {value!r}")
        value = tuple(value)
        if kind in ("Range", "IntRange", "tuple[int, int]") and len(value) != 2:
            raise ValueError(f"config field {f.name!r}: expected 2 values (low, high), got {value!r}")
        if kind == "Range":
            value = tuple(_number(f.name, v, float) for v in value)
        elif kind in ("IntRange", "tuple[int, int]"):
            value = tuple(_number(f.name, v, int) for v in value)
    elif kind == "float":
        value = _number(f.name, value, float)
    elif kind == "int":
        value = _number(f.name, value, int)
    elif kind == "bool" and not isinstance(value, bool):
        raise ValueError(f"config field {f.name!r}: expected true or false, got {value!r}")
    return value


def _number(name: str, value: Any, kind: type) -> float | int:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f"config field {name!r}: expected a number, got {value!r}")
    if kind is int and value != int(value):
        raise ValueError(f"config field {name!r}: expected an integer, got {value!r}")
    if not math.isfinite(value):
        raise ValueError(f"config field {name!r}: expected a finite number, got {value!r}")
    return kind(value)


RANGE_BOUNDS: dict[str, tuple[float, float]] = {
    "camera_height": (1e-3, math.inf), "fov_deg": (1.0, 170.0), "n_lights": (0, 8),
    "light_height": (1e-3, math.inf), "light_irradiance": (0.0, math.inf),
    "spot_irradiance": (0.0, math.inf), "area_irradiance": (0.0, math.inf),
    "spot_cone_deg": (1.0, 114.0), "ambient": (0.0, math.inf), "n_occluders": (0, 16),
    "occluder_height": (0.0, math.inf), "occluder_size": (1e-4, math.inf),
    "plane_roughness": (0.0, 1.0), "plane_metallic": (0.0, 1.0), "plane_specular": (0.0, 1.0),
    "plane_coat": (0.0, 1.0), "plane_coat_roughness": (0.0, 1.0),
    "background_level": (0.0, 1.0), "exposure_stops": (-8.0, 8.0), "gamma": (0.1, 10.0),
    "read_noise": (0.0, 1.0), "shot_noise": (0.0, 1.0), "jpeg_quality": (1, 100),
}
"""Allowed ``(lowest low, highest high)`` of the bounded range fields."""


def _validate(c: SidarConfig) -> None:
    def need(ok: bool, name: str, expected: str) -> None:
        if not ok:
            raise ValueError(f"config field {name!r}: expected {expected}, got {getattr(c, name)!r}")

    need(all(s >= 1 for s in c.image_size), "image_size", "(H, W) with H, W >= 1")
    need(c.n_views >= 1, "n_views", "at least 1")
    need(c.camera_xy >= 0, "camera_xy", ">= 0")
    need(c.max_tilt_deg >= 0 and c.max_tilt_deg < 90, "max_tilt_deg", "0 <= max_tilt_deg < 90")
    need(c.light_xy >= 0, "light_xy", ">= 0")
    need(c.occluder_xy >= 0, "occluder_xy", ">= 0")
    need(0 <= c.min_coverage <= 1, "min_coverage", "a fraction in [0, 1]")
    need(0 <= c.min_overlap <= 1, "min_overlap", "a fraction in [0, 1]")
    need(c.shadow_filter in SHADOW_FILTERS, "shadow_filter", f"one of {SHADOW_FILTERS}")
    need(c.on_bad_image in ON_BAD_IMAGE, "on_bad_image", f"one of {ON_BAD_IMAGE}")
    need(c.background in BACKGROUNDS, "background", f"one of {BACKGROUNDS}")
    need(0 <= c.light_saturation_max <= 1, "light_saturation_max", "a value in [0, 1]")
    need(c.area_light_size > 0, "area_light_size", "> 0")
    need(c.area_light_samples >= 1, "area_light_samples", "at least 1")
    need(0 <= c.mask_min_opacity <= 1, "mask_min_opacity", "a value in [0, 1]")
    size = c.shadow_map_size
    need(size >= 16 and size & (size - 1) == 0, "shadow_map_size", "a power of two >= 16")
    need(c.shadow_frustum in SHADOW_FRUSTA, "shadow_frustum", f"one of {SHADOW_FRUSTA}")
    need(c.mesh_detail in MESH_DETAILS, "mesh_detail", f"one of {MESH_DETAILS}")
    need(c.mesh_error_px >= 0, "mesh_error_px", ">= 0 (pixels)")
    need(c.texture_filter in TEXTURE_FILTERS, "texture_filter", f"one of {TEXTURE_FILTERS}")
    need(len(c.light_types) > 0 and set(c.light_types) <= set(LIGHT_TYPES),
         "light_types", f"a non-empty subset of {LIGHT_TYPES}")
    need(len(c.occluder_shapes) > 0 and set(c.occluder_shapes) <= set(OCCLUDER_SHAPES),
         "occluder_shapes", f"a non-empty subset of {OCCLUDER_SHAPES}")
    need(len(c.occluder_materials) > 0 and set(c.occluder_materials) <= set(OCCLUDER_MATERIALS),
         "occluder_materials", f"a non-empty subset of {OCCLUDER_MATERIALS}")
    for name, (lo, hi) in RANGE_BOUNDS.items():
        low, high = getattr(c, name)
        need(lo <= low <= high <= hi, name, f"a range (low, high) with {lo} <= low <= high <= {hi}")
    samples = c.area_light_samples if "area" in c.light_types else 1
    need(c.n_lights[1] * samples <= MAX_SHADOWED_LIGHTS, "area_light_samples",
         f"n_lights[1] * area_light_samples <= {MAX_SHADOWED_LIGHTS} (shadow maps the renderer can bind)")


def _check_names(values: Mapping[str, Any], what: str) -> None:
    known = {f.name for f in dataclasses.fields(SidarConfig)}
    unknown = sorted(set(values) - known)
    if unknown:
        raise ValueError(f"unknown config {what} {unknown}; known fields: {sorted(known)}")


def available_presets() -> list[str]:
    """Names of the YAML presets in ``configs/``."""
    return sorted(p.stem for p in CONFIG_DIR.glob("*.yaml"))


def _read_yaml(source: str | os.PathLike, seen: tuple[Path, ...] = ()) -> dict[str, Any]:
    """Fields of a preset name or YAML path, with its ``base`` chain resolved (base first)."""
    path = Path(source)
    if path.suffix not in (".yaml", ".yml"):
        if str(source) not in available_presets():
            raise ValueError(f"config {str(source)!r}: not a preset ({available_presets()}) nor a YAML path")
        path = CONFIG_DIR / f"{source}.yaml"
    if not path.is_file():
        raise FileNotFoundError(f"config file {str(path)!r} does not exist")
    if path.resolve() in seen:
        raise ValueError(f"config {str(path)!r}: 'base' chain loops back to itself")
    data = yaml.safe_load(path.read_text()) or {}
    if not isinstance(data, dict):
        raise ValueError(f"config {str(path)!r}: expected a mapping of fields, got {type(data).__name__}")
    base = data.pop("base", None)
    _check_names(data, f"field in {str(path)!r}:")
    if base is None:
        return data
    base_path = base if str(base) in available_presets() else path.parent / str(base)
    return {**_read_yaml(base_path, seen + (path.resolve(),)), **data}


def load_config(preset: str | os.PathLike | SidarConfig | None = "misaligned", **overrides: Any) -> SidarConfig:
    """Load a preset by name (``configs/<name>.yaml``) or a YAML path, and apply keyword overrides.

    Args:
        preset: preset name, path to a YAML file, an existing ``SidarConfig``, or ``None`` for the
            built-in defaults.
        **overrides: field values replacing the preset's, e.g. ``image_size=(384, 512)``,
            ``n_lights=(0, 2)``.

    Raises:
        ValueError: unknown preset or field, or a value out of its allowed range (the message
            names the field).
    """
    _check_names(overrides, "override")
    if isinstance(preset, SidarConfig):
        return preset.replace(**overrides)
    fields = {} if preset is None else _read_yaml(preset)
    return SidarConfig(**{**fields, **overrides})
