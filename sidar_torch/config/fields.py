"""``SidarConfig``: every field of a SIDAR scene and its renderer, with its meaning as field metadata.

Each field is declared with :func:`_field`, whose ``metadata`` holds ``meaning`` (one sentence or
more, the text ``python -m sidar_torch schema`` prints), and where they apply ``bounds`` (the
``(lowest, highest)`` value of a number, of each side of a size, or of a range's ends) or
``choices`` (the allowed words of a text field, or numbers of ``antialias``): every number field
has one or the other, finite bounds derived in ``allowed`` from what renders. Validation
(``validation``) and the schema (``schema``) read the metadata; nothing parses this module's
docstrings.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

from .allowed import (ANTIALIAS_SAMPLES, AREA_LIGHT_SHADINGS, BACKGROUNDS, GEOMETRY_DTYPES, LENS_MODELS, LIGHT_TYPES, MAX_CAMERA_DISTANCE, MAX_GL_SIZE,
                      MAX_LIGHT_INTENSITY, MAX_LIGHT_LEVEL, MAX_SAMPLE_BYTES, MAX_SCENE_EXTENT, MAX_SHADOWED_LIGHTS, MAX_VIEWS, MESH_DETAILS,
                      OCCLUDER_MATERIALS, OCCLUDER_SHAPES, ON_BAD_IMAGE, SHADOW_FILTERS, SHADOW_FRUSTA, SPOT_FALLOFFS,
                      TEXTURE_FILTERS)
from .validation import check_names, coerce, validate

__all__ = ["SidarConfig", "field_meaning"]

Range = tuple[float, float]
IntRange = tuple[int, int]
MapSize = "int | str"
"""A shadow map's side: a power of two, or ``"auto"`` (``choices.render.shadow_map_side``)."""


def _field(default: Any, *, meaning: str, bounds: tuple[float, float] | None = None,
           choices: tuple[str | int, ...] | None = None) -> Any:
    """A dataclass field with its ``meaning`` and, where given, ``bounds`` (``(lowest, highest)``, both
    allowed) and ``choices`` as metadata."""
    metadata = {"meaning": meaning}
    if bounds is not None:
        metadata["bounds"] = bounds
    if choices is not None:
        metadata["choices"] = choices
    return dataclasses.field(default=default, metadata=metadata)


def field_meaning(name: str) -> str:
    """The meaning of the ``SidarConfig`` field ``name`` (its ``metadata["meaning"]``)."""
    return SidarConfig.__dataclass_fields__[name].metadata["meaning"]


# Meanings shared by fields described together.
_LIGHT_BOX = f"light position box, like the cameras' (at most {MAX_SCENE_EXTENT:g} painting units)."
_IRRADIANCE = (
    f"ranges (at most {MAX_LIGHT_LEVEL:g}, where every lit texel is white) of a point, spot and area light's "
    "irradiance at the painting's centre (an area light's summed "
    "over its emitters). The defaults keep the paper's power ratios (point 1-3.5 kW, spot 1-10 kW, area 1-2 "
    "kW radiating into a half-space, i.e. 4-8 kW point-equivalent) at a scale chosen so that the fraction "
    "of blown-out painting pixels matches the paper's renders (``python -m benchmarks.exposure``).")
_INTENSITY = (
    "ranges of a point, spot and area light's intensity: the irradiance it gives at one painting unit on its axis "
    "(the renderer's linear units; an area light's summed over its emitters, before its spread narrows it). ``(0, 0)``, the default: no draw, the "
    "light's strength is drawn as its irradiance at the painting's centre (``*_irradiance``), whatever its "
    "distance. Otherwise the intensity is drawn, and the centre gets ``intensity cos / d**2`` from the light's "
    "drawn position (``d`` its distance, ``cos`` the incidence there), as the paper's generator draws each light's "
    "power (point 1-3.5 kW, spot 1-10 kW: ``P / (4 pi 7**2)``; area 1-2 kW: ``P / (pi 7**2)``, 7 Blender units to "
    "the painting unit): a far light is a dim one.")
_OCCLUDER_KINDS = "kinds to draw from."
_OCCLUDER_BOX = f"box of occluder centres (at most {MAX_SCENE_EXTENT:g} painting units)."
_PLANE_MATERIAL = "ranges of the painting's material."
_LENS = ("range of a lens coefficient (``lens_model``) at the image's corner, drawn per view: ``k1 r^2``, ``k2 r^4``, "
         "``k3 r^6``, ``p1 r``, ``p2 r`` (brown_conrady) or ``lambda r^2`` (division), ``r`` the corner's normalised "
         "radius ``|K^-1 (u, v, 1)|``, so a lens bends every field of view alike (``k1 = -0.1``: the corner 10 % "
         "closer to the centre); the sample's ``lens`` holds the coefficients themselves. The ranges' ends must "
         "not fold the image before its corner, tangential terms included (checked).")
_COAT = ("ranges of the weight and roughness of a clear coat on the painting (a second, sharper specular lobe "
         "with 4 % reflectance).")


@dataclass(frozen=True)
class SidarConfig:
    """Every parameter of the scene sampler and renderer (frozen).

    Units. Lengths are in *painting units*: the painting's shorter side is 1 (the paper's Blender
    scenes use 7 Blender units for it, so its ranges are divided by 7 here). Angles are in degrees.
    Light strength is the irradiance a light gives the painting's centre, in the renderer's linear
    units, where a white diffuse painting saturates at about 3.3 (see ``sidar_torch.render``).
    Sizes are ``(H, W)``. A range is a pair ``(low, high)`` with ``low <= high``; values are drawn
    uniformly from it. Each field's meaning is its metadata (:func:`field_meaning`;
    ``python -m sidar_torch schema`` prints them all). Numbers may be Python, NumPy or 0-d torch
    scalars (see ``sidar_torch.config.numbers``).
    """

    # Output
    image_size: tuple[int, int] = _field((384, 512), bounds=(1, MAX_GL_SIZE), meaning=(
        f"``(H, W)`` of every view, mask and label, in pixels; each at most {MAX_GL_SIZE} (the largest "
        "renderbuffer and texture side of Mesa's llvmpipe, ``GL_MAX_RENDERBUFFER_SIZE``), and with ``n_views`` "
        f"and the shadow maps within the {MAX_SAMPLE_BYTES / 2**30:g} GiB a sample may need, estimated as "
        "``H W (32 V + 96 + 8 antialias) + 32768 V^2 + 6 maps shadow_map_size^2`` bytes (measured; "
        "``sidar_torch.config.memory``): e.g. up to about 3180 x 4240 at 6 views."))
    n_views: int = _field(6, bounds=(1, MAX_VIEWS), meaning=(
        "number of views ``V`` per sample; view 0 is the fronto-parallel reference. At most "
        f"{MAX_VIEWS} (the homographies and their check need about 32 KiB per ordered pair of views), and "
        "within a sample's memory with ``image_size``."))
    geometry_dtype: str = _field("float32", choices=GEOMETRY_DTYPES, meaning=(
        "dtype of the handed-out ``homographies``, ``K``, ``R`` and ``t``: ``\"float32\"`` or ``\"float64\"`` "
        "(computed in float64 either way; chaining homographies, e.g. ``H[k, j] @ H[i, k]`` at grazing views, "
        "needs float64)."))

    # Cameras
    aligned: bool = _field(False, meaning="every view through the reference camera (all homographies identity).")
    camera_xy: float = _field(5 / 7, bounds=(0.0, MAX_CAMERA_DISTANCE), meaning=(
        "half-width of the square in which camera x and y are drawn (at most "
        f"{MAX_CAMERA_DISTANCE:g}: views that far still render with finite, accurate homographies)."))
    camera_height: Range = _field((5 / 7, 1.0), bounds=(1e-3, MAX_CAMERA_DISTANCE), meaning=(
        "range of camera z (distance above the painting's plane)."))
    reference_height: Range = _field((0.0, 0.0), bounds=(0.0, MAX_CAMERA_DISTANCE), meaning=(
        "range of the reference camera's z (view 0, fronto-parallel, its view exactly the painting); "
        "``(0, 0)``, the default, draws it from ``camera_height`` like the other views. Otherwise both ends at least 1e-3. The paper's front camera is "
        "10 Blender units above the painting (``10/7``): from there its occluders, 1-5 units high, lie "
        "over the painting far more often than from a camera 5-7 units high."))
    fov_deg: Range = _field((61.9, 100.4), bounds=(1.0, 170.0), meaning=(
        "range of the field of view across the longer image side, for views 1..V-1."))
    focal_uniform: bool = _field(False, meaning=(
        "draw the focal length of views 1..V-1 uniformly between those of ``fov_deg``'s ends (``1 / tan(fov / 2)`` "
        "uniform), as the paper's generator draws its lens (15-30 mm on a 36 mm sensor: 100.4-61.9 degrees), "
        "instead of the angle (the same single draw either way)."))
    max_tilt_deg: float = _field(90.0, bounds=(0.0, 90.0), meaning=(
        "largest angle between a camera's axis and the painting's normal: cameras are drawn from the "
        "``camera_xy`` x ``camera_height`` box, then limited to this tilt (90: no limit). The box itself "
        "tilts at most ``atan(sqrt(2) camera_xy / camera_height[0])`` (54.7 deg by default), so a larger "
        "value is refused: for grazing views raise ``camera_xy`` or lower ``camera_height``."))
    min_coverage: float = _field(0.0, bounds=(0.0, 1.0), meaning=(
        "least fraction of each view's pixels that see the painting (cameras are redrawn until it holds; see "
        "``sidar_torch.scene``)."))
    min_overlap: float = _field(0.0, bounds=(0.0, 1.0), meaning=(
        "least fraction of the painting pixels of any view ``i`` that another view ``j`` also sees (every "
        "ordered pair; cameras are redrawn until it holds)."))

    # Scene content (drawn afresh for every view unless ``scene_per_view`` is false)
    n_lights: IntRange = _field((2, 4), bounds=(0, 8), meaning="range of the number of lights.")
    light_types: tuple[str, ...] = _field(LIGHT_TYPES, choices=LIGHT_TYPES, meaning=(
        "light kinds to draw from (``spot``, ``point``, ``area``)."))
    light_xy: float = _field(10 / 7, bounds=(0.0, MAX_SCENE_EXTENT), meaning=_LIGHT_BOX)
    light_height: Range = _field((10 / 7, 15 / 7), bounds=(1e-3, MAX_SCENE_EXTENT), meaning=_LIGHT_BOX)
    light_irradiance: Range = _field((0.5, 1.75), bounds=(0.0, MAX_LIGHT_LEVEL), meaning=_IRRADIANCE)
    spot_irradiance: Range = _field((0.5, 5.0), bounds=(0.0, MAX_LIGHT_LEVEL), meaning=_IRRADIANCE)
    area_irradiance: Range = _field((2.0, 4.0), bounds=(0.0, MAX_LIGHT_LEVEL), meaning=_IRRADIANCE)
    light_intensity: Range = _field((0.0, 0.0), bounds=(0.0, MAX_LIGHT_INTENSITY), meaning=_INTENSITY)
    spot_intensity: Range = _field((0.0, 0.0), bounds=(0.0, MAX_LIGHT_INTENSITY), meaning=_INTENSITY)
    area_intensity: Range = _field((0.0, 0.0), bounds=(0.0, MAX_LIGHT_INTENSITY), meaning=_INTENSITY)
    light_saturation_max: float = _field(0.3, bounds=(0.0, 1.0), meaning="colour is HSV(U(0, 1), U(0, this), 1).")
    spot_cone_deg: Range = _field((10.0, 90.0), bounds=(1.0, 114.0), meaning="range of a spot light's full cone angle.")
    spot_falloff: str = _field("quadratic", choices=SPOT_FALLOFFS, meaning=(
        "how a spot light fades from its inner to its outer cone. ``quadratic``: pyrender's, the square of a "
        "linear ramp in cos(angle), the inner cone ``outer x (1 - u)``; ``blender``: Blender's spot blend, "
        "a smoothstep of that ramp, the inner cone where ``cos = cos(outer) + (1 - cos(outer)) u`` (``u`` the "
        "blend, uniform in [0, 1] either way)."))
    area_light_size: float = _field(0.3, bounds=(1e-4, MAX_SCENE_EXTENT), meaning=(
        f"side of a square area light (at most {MAX_SCENE_EXTENT:g} painting units)."))
    area_spread_deg: Range = _field((180.0, 180.0), bounds=(1.0, 180.0), meaning=(
        "range of an area light's spread (Blender's), the full angle of the cone it emits into. ``(180, 180)``: "
        "the whole half-space, lighting the painting evenly (no draw then, so such configs draw the same scenes "
        "as before the field existed); below 180, a beam aimed at the painting's centre with the same power and "
        "Cycles' profile, ``cos t (1 - tan t / tan a)`` at angle ``t`` from its axis (``a`` half the spread), so "
        "the narrower the brighter its centre (``sidar_torch.scene.spread_beam``; cones wider than 114 degrees "
        "are capped there)."))
    area_light_samples: int = _field(4, bounds=(1, MAX_SHADOWED_LIGHTS), meaning=(
        "jittered shadow-casting samples an area light is made of (``n_lights`` high end times this at most "
        f"{MAX_SHADOWED_LIGHTS}, the shadow maps the renderer can bind, when ``area`` lights are drawn)."))
    area_light_shading: str = _field("per_light", choices=AREA_LIGHT_SHADINGS, meaning=(
        'how an area light of several samples shades a point: ``"per_light"`` (the default), its light and '
        'highlight evaluated once, from its centre, and dimmed by the mean of its samples\' shadow lookups (one '
        'highlight, and 12-15 % less CPU per ``misaligned`` view: docs/rendering.md), or ``"per_emitter"``, each sample '
        'evaluated and shadowed on its own (a highlight per sample). Lights of one emitter shade the same '
        'either way.'))
    ambient: Range = _field((0.0, 0.02), bounds=(0.0, MAX_LIGHT_LEVEL), meaning=(
        f"range of the ambient light level (linear, 1 reproduces the texture; at most {MAX_LIGHT_LEVEL:g}, where "
        "every non-black texel is white)."))
    n_occluders: IntRange = _field((0, 3), bounds=(0, 16), meaning="range of the number of occluding objects.")
    occluder_shapes: tuple[str, ...] = _field(OCCLUDER_SHAPES, choices=OCCLUDER_SHAPES, meaning=_OCCLUDER_KINDS)
    occluder_materials: tuple[str, ...] = _field(OCCLUDER_MATERIALS, choices=OCCLUDER_MATERIALS,
                                                 meaning=_OCCLUDER_KINDS)
    occluder_xy: float = _field(3 / 7, bounds=(0.0, MAX_SCENE_EXTENT), meaning=_OCCLUDER_BOX)
    occluder_height: Range = _field((1 / 7, 5 / 7), bounds=(0.0, MAX_SCENE_EXTENT), meaning=_OCCLUDER_BOX)
    occluder_size: Range = _field((0.1 / 7, 1.1 / 7), bounds=(1e-4, MAX_SCENE_EXTENT), meaning=(
        f"range of an occluder's half-extent along each of its axes (at most {MAX_SCENE_EXTENT:g} painting units)."))
    paper_torus: bool = _field(False, meaning=(
        "every torus at the size of the paper's, Blender's default torus, which it never scales (major radius 1, "
        "minor 0.25 Blender units): outer radius 1.25 / 7 and half-thickness 0.25 / 7, with no draw from "
        "``occluder_size`` (see ``sidar_torch.scene.PAPER_TORUS_SCALE``)."))
    paper_rotation: bool = _field(False, meaning=(
        "every occluder's rotation drawn as the paper's generator draws it: three Euler angles each uniform in "
        "[0, 2 pi), in Blender's XYZ order (``Rz Ry Rx``), which favours some orientations (a torus's axis lies "
        "nearer the painting's plane), instead of uniformly over all rotations (three draws instead of four)."))
    paper_occluder_materials: bool = _field(False, meaning=(
        "occluder colours and factors drawn as the paper's Blender materials draw them: colour uniform in linear "
        "RGB (each channel U(0, 1), not HSV), roughness U(0, 0.5) for the ``glossy``, ``metallic`` and "
        "``transparent`` kinds, and a ``principled`` occluder with the Principled BSDF's ranges (roughness "
        "U(0, 0.5), metallic, specular, coat, coat roughness and transmission U(0, 1)); ``glass`` and "
        "``transparent`` occluders filter the painting behind by that colour squared (the paper's Glass and "
        "Transparent BSDFs tint light at both of a body's surfaces; a transparent one has no shading of its own). "
        "See ``sidar_torch.scene.kinds``."))
    glass_shadows_opaque: bool = _field(False, meaning=(
        "``glass`` occluders cast shadows as dark as opaque ones, as the paper's glass and refraction materials "
        "do in Cycles (refracted light from a light source carries no direct light); false: a tinted, lighter "
        "shadow like a ``transparent`` occluder's."))
    glass_saturation: Range = _field((0.0, 0.3), bounds=(0.0, 1.0), meaning=(
        "range of the saturation of a ``glass`` occluder's tint (HSV, hue uniform, value 1). The tint colours "
        "the painting seen through the glass, as a glass BSDF's colour does. The paper's glass and "
        "refraction materials draw their colour uniformly in RGB: ``(0, 1)``."))
    occluders_visible: bool = _field(True, meaning=(
        "false makes occluders invisible to cameras; they still cast shadows."))
    mask_min_opacity: float = _field(0.0, bounds=(0.0, 1.0), meaning=(
        "occluders whose material opacity (alpha) is below this are left out of the masks: the painting seen "
        "through them counts as visible. 0 (the paper's choice) masks every occluder, however transparent."))
    opacity_output: bool = _field(False, meaning=(
        "also hand out ``opacities``, a soft mask per view: the fraction of the painting hidden at each pixel "
        "(1 off the painting and behind opaque occluders, 0 where it is seen unobstructed, ``1 - prod(1 - "
        "a_k)`` through transparent occluders of opacity ``a_k``), whatever ``mask_min_opacity`` is. Costs one "
        "unlit draw per view."))
    shadow_mask_output: bool = _field(False, meaning=(
        "also hand out ``shadow_masks``, per view the fraction of the direct light falling on the visible "
        "painting that occluders block (each light weighted by its irradiance there, coloured shadows of "
        "transparent occluders by their luminance; 0 off the painting and where it is hidden). Costs one draw "
        "of the painting per view with a shadowed light; see docs/rendering.md, \"Shadow masks\"."))
    shadow_free_output: bool = _field(False, meaning=(
        "also hand out ``shadow_free``, each view rendered from the same scene (lights, occluders, cameras, view "
        "effects and noise) with no light blocked: the target of shadow removal in the view's own lighting. "
        "Occluders stay in the picture and the masks do not change. Costs a second output of the colour draw "
        "(and its readback) per view with a shadowed light; see docs/rendering.md, \"Shadow masks\"."))
    depth_output: bool = _field(False, meaning=(
        "also hand out ``depth``, per view the distance along the camera's z axis (painting units, float32) to "
        "the nearest surface the mask counts (the painting, or an occluder at least ``mask_min_opacity`` opaque: "
        "by default every occluder, transparent ones included), ``inf`` where none is hit; "
        "``sidar_torch.flow`` turns it into dense correspondence. Costs one untextured draw per view; see "
        "docs/parallax.md."))
    flow_output: bool = _field(False, meaning=(
        "also hand out ``flow_to_reference``, per view where each pixel lands in view 0 minus the pixel (pixels, "
        "float32 ``(du, dv)``), NaN where that is not a seen correspondence: ``sidar_torch.flow(sample, i, 0)`` "
        "for every view, computed on the CPU from the depth (drawn for it whether or not ``depth_output`` is on); "
        "needs an ``image_size`` of at least 2 x 2. See docs/parallax.md."))
    normals_output: bool = _field(False, meaning=(
        "also hand out ``normals``, per view the unit surface normal in the camera's frame (x right, y down, "
        "z forward; float32 ``(3, H, W)``) of the nearest surface the mask counts, facing the camera, 0 where "
        "none is hit: for relighting and intrinsic-image models. Costs one untextured draw per view; pinhole "
        "cameras only (lens_model none)."))
    shadows: bool = _field(True, meaning="whether lights cast shadows.")
    plane_roughness: Range = _field((0.4, 1.0), bounds=(0.0, 1.0), meaning=_PLANE_MATERIAL)
    plane_metallic: Range = _field((0.0, 0.2), bounds=(0.0, 1.0), meaning=_PLANE_MATERIAL)
    plane_specular: Range = _field((0.0, 1.0), bounds=(0.0, 1.0), meaning=(
        "range of the painting's specular level (dielectric reflectance at normal incidence ``0.08 * level``, "
        "Blender's convention: 0.5 is 4 %)."))
    plane_coat: Range = _field((0.0, 1.0), bounds=(0.0, 1.0), meaning=_COAT)
    plane_coat_roughness: Range = _field((0.03, 0.3), bounds=(0.0, 1.0), meaning=_COAT)
    plane_transmission: Range = _field((0.0, 0.0), bounds=(0.0, 1.0), meaning=(
        "range of the painting's transmission (Blender's Principled ``Transmission Weight``): the share of its "
        "diffuse light that passes through the painting into the black world below and is lost, so the diffuse "
        "light is scaled by ``1 - transmission`` (the specular lobes and the metallic part are unchanged). "
        "``(0, 0)`` draws nothing, so a config without it draws the same scenes as before the field existed."))
    plane_diffuse: bool = _field(False, meaning=(
        "a purely diffuse painting (metallic 0, roughness 1, no specular, no coat), overriding the other "
        "``plane_*`` ranges."))
    scene_per_view: bool = _field(True, meaning="draw new lights, occluders and painting material for every view.")

    # Rendering
    shadow_map_size: MapSize = _field("auto", bounds=(16, MAX_GL_SIZE), meaning=(
        f"side of each shadow map in texels (a power of two from 16 to {MAX_GL_SIZE}, the largest texture "
        "side of Mesa's llvmpipe, ``GL_MAX_TEXTURE_SIZE``), or ``auto``: the smallest power of two at least the "
        "image's longer side, from 512 to 2048 (about one texel per pixel across a fitted frustum; 512 at "
        "384 x 512, 1024 at 768 x 1024). A view holds one map per shadowed emitter, 6 bytes per texel, counted "
        "in a sample's memory (see ``image_size``)."))
    shadow_filter: str = _field("bilinear", choices=SHADOW_FILTERS, meaning=(
        'how a shadow-map lookup is filtered: ``"bilinear"``, a 2 x 2 percentage-closer filter from one '
        'depth-compare tap (the default: closer to a 4096-map reference than the tent at every map size, for a '
        'quarter of the texture reads), or ``"tent"``, a 3 x 3 tent-weighted filter from 4 bilinear taps (shadow '
        "edges one texel softer)."))
    light_radius: float = _field(0.0, bounds=(0.0, 0.5), meaning=(
        "radius of every light's emitters, painting units: 0 (the default) casts hard shadows through "
        "``shadow_filter``; above 0, soft ones (percentage-closer soft shadows: a penumbra that grows with the "
        "distance from the caster, ``light_radius`` times receiver distance over caster distance, less one). "
        "Blender's default light radius is 0.25 units, ``0.25 / 7``."))

    # View effects (beyond the paper; each off by default. Per-pixel effects on the rendered views
    # only, drawn after the scene so switching one on changes no scene, mask, label or homography;
    # see ``sidar_torch.sample.effects``)
    background: str = _field("black", choices=BACKGROUNDS, meaning=(
        'what the views show where nothing was drawn: ``"black"`` (the paper\'s), ``"view"`` (a random colour '
        'per view) or ``"sequence"`` (one random colour per sample).'))
    background_level: Range = _field((0.0, 1.0), bounds=(0.0, 1.0), meaning=(
        "range each 8-bit sRGB channel of a background colour is drawn from, as a fraction of 255."))
    pixel_filter_sigma: float = _field(0.0, bounds=(0.0, 4.0), meaning=(
        "standard deviation, in pixels, of a Gaussian pixel filter on the views (and ``shadow_free``) in linear "
        "light, before exposure and noise; 0: none (each pixel its own area, a box filter). Cycles filters "
        "every pixel (Blackman-Harris, 1.5 px wide by default) and denoises; the ``paper_*`` presets take the "
        "sigma that gives their views the paper's measured blur (``python -m benchmarks.blur``, "
        "docs/realism.md). Masks, opacities, shadow masks and the label are never filtered."))
    texture_blur_sigma: float = _field(0.0, bounds=(0.0, 4.0), meaning=(
        "standard deviation, in texels, of a Gaussian blur of the painting's texture in linear light, as the views "
        "(and ``shadow_free`` and the painting's reflections) see it; 0: the painting as it is. Cycles filters an "
        "image texture (the paper's label is 0.75 px blurrier than its painting) while its denoiser keeps "
        "occluder outlines sharp: unlike ``pixel_filter_sigma`` this leaves outlines alone (docs/realism.md). "
        "The label, masks and opacities are never blurred."))
    exposure_jitter: bool = _field(False, meaning=(
        "scale each view's linear intensity by ``2 ** stops`` and raise it to a power ``gamma`` (drawn per "
        "view)."))
    exposure_stops: Range = _field((-1.0, 1.0), bounds=(-8.0, 8.0), meaning=(
        "range of the exposure change, in stops (EV)."))
    gamma: Range = _field((0.8, 1.25), bounds=(0.1, 10.0), meaning=(
        "range of the exponent applied to a view's linear intensity (after exposure and noise)."))
    sensor_noise: bool = _field(False, meaning=(
        "add Gaussian read noise and signal-dependent shot noise in linear light."))
    read_noise: Range = _field((0.0, 0.01), bounds=(0.0, 1.0), meaning=(
        "range of a view's read-noise standard deviation (linear intensity, 1 is white)."))
    shot_noise: Range = _field((0.0, 0.002), bounds=(0.0, 1.0), meaning=(
        "range of a view's shot-noise scale ``k``: variance ``k * x`` at linear intensity ``x`` (a Poisson "
        "count of ``x / k`` photons, times ``k``; Gaussian approximation)."))
    jpeg: bool = _field(False, meaning="compress each view as JPEG and decode it (Pillow, in memory, 4:2:0 chroma).")
    jpeg_quality: IntRange = _field((30, 95), bounds=(1, 100), meaning=(
        "range of a view's JPEG quality (Pillow's scale, 1-100)."))
    # Lens (off by default; drawn from a generator of its own, so switching it on changes no other draw;
    # see ``sidar_torch.choices.lenses`` and docs/lens.md)
    lens_model: str = _field("none", choices=LENS_MODELS, meaning=(
        'each view\'s lens: ``"none"`` (a pinhole camera, the default), ``"brown_conrady"`` (OpenCV\'s radial and '
        'tangential ``(k1, k2, p1, p2, k3)``) or ``"division"`` (Fitzgibbon\'s ``lambda``). Every view (view 0 '
        "too) and every per-view image output is distorted, the label is not; ``K`` and ``homographies`` stay "
        "those of the undistorted views, the sample's ``lens`` holds each view's coefficients."))
    lens_k1: Range = _field((-0.1, 0.05), bounds=(-0.5, 0.5), meaning=_LENS)
    lens_k2: Range = _field((0.0, 0.03), bounds=(-0.5, 0.5), meaning=_LENS)
    lens_k3: Range = _field((0.0, 0.0), bounds=(-0.5, 0.5), meaning=_LENS)
    lens_p1: Range = _field((-0.002, 0.002), bounds=(-0.01, 0.01), meaning=_LENS)
    lens_p2: Range = _field((-0.002, 0.002), bounds=(-0.01, 0.01), meaning=_LENS)
    lens_lambda: Range = _field((-0.15, 0.05), bounds=(-0.5, 0.5), meaning=_LENS)
    distortion_map_output: bool = _field(False, meaning=(
        "also hand out ``distortion_maps`` (with a lens): per view and distorted pixel, where it comes from in "
        "the undistorted view, Kornia pixels."))
    shadow_frustum: str = _field("fitted", choices=SHADOW_FRUSTA, meaning=(
        'what a spot light\'s shadow map covers: ``"cone"`` (pyrender\'s frustum, 2 x outer cone + pi / 16 wide) '
        'or ``"fitted"`` (only what the cameras see of the painting and occluders, within the cone: the same '
        "map size gives finer shadows; the default, as the sweep found it closer to the reference at every map "
        "size for the same time)."))
    mesh_detail: str = _field("auto", choices=MESH_DETAILS, meaning=(
        '``"auto"`` (the default): per view, the coarsest of 4 pooled levels whose silhouette and shadow stay '
        'within ``mesh_error_px`` of the true surface; ``"fixed"``: every curved occluder (sphere, cylinder, '
        "cone, torus, capsule) uses one mesh (icosphere 3, 48 sections), which facets close ones."))
    mesh_error_px: float = _field(0.25, bounds=(0.0, MAX_GL_SIZE), meaning=(
        'the largest silhouette error, in pixels, ``mesh_detail`` "auto" allows (0: always the finest level; at '
        f"most {MAX_GL_SIZE}, an image's largest side)."))
    highlight_spill: bool = _field(True, meaning=(
        "over-exposed light spills into the other channels, so a blown-out red turns white; false: each "
        "channel clips at white on its own, as Blender's Standard view transform does (the paper's renders)."))
    antialias: int = _field(1, choices=ANTIALIAS_SAMPLES, meaning=(
        "samples per pixel of each view's lit colour pass: 1 (none, the default: jagged silhouettes) or 2, 4, 8 "
        "(multisample antialiasing, resolved to one colour per pixel; the OpenGL context must offer the count, "
        "Mesa's llvmpipe offers only 4). Masks stay binary (drawn single-sampled, by the paper's rule); "
        "opacities and the label are drawn single-sampled too. Cost and gain: docs/rendering.md, \"Edges\"."))
    texture_filter: str = _field("trilinear", choices=TEXTURE_FILTERS, meaning=(
        'the painting texture\'s filter, ``"trilinear"`` (mipmapped), ``"bilinear"`` (full-size texture only; '
        'aliases where a view shrinks the painting) or ``"supersampled"`` (the mean of 2 x 2 trilinear lookups spread '
        "over the pixel's footprint where a view shrinks the painting, each at a finer mipmap level: oblique and "
        "distant views as sharp as a path tracer's, as in the paper's Blender renders, without aliasing; the same "
        "as trilinear where the view does not shrink it, and the label exact; docs/realism.md)."))

    # Input
    on_bad_image: str = _field("raise", choices=ON_BAD_IMAGE, meaning=(
        'what a painting source does with an unreadable image: ``"raise"`` (an error naming the file) or '
        '``"skip"`` (a warning, and the next readable image).'))
    max_image_pixels: int = _field(2**28, bounds=(1, 2**34), meaning=(
        "the most pixels (width x height, read from the file's header before anything is decoded) an image "
        "file may have; a larger one is an unreadable image (``on_bad_image``). The default, 2**28 "
        "(268,435,456, e.g. 16384 x 16384), is far above any real painting and stops a small file that "
        "claims a huge size (a decompression bomb) before it takes the memory; Pillow's own process-wide "
        "limit ``PIL.Image.MAX_IMAGE_PIXELS`` applies too (see docs/failures.md). At most 2**34: decoding "
        "takes about 3 bytes a pixel."))

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            object.__setattr__(self, f.name, coerce(f, getattr(self, f.name)))
        validate(self)

    def replace(self, **overrides: Any) -> "SidarConfig":
        """Return a copy with some fields changed (validated like the constructor)."""
        check_names(overrides, type(self), "override")
        return dataclasses.replace(self, **overrides)

    def to_dict(self) -> dict[str, Any]:
        """Plain-data view (lists for tuples), suitable for YAML or JSON."""
        return {k: list(v) if isinstance(v, tuple) else v for k, v in dataclasses.asdict(self).items()}
