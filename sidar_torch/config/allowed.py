"""What config fields may hold: the choices of the text fields and the limits the renderer imposes (the
renderer's own choices come from :mod:`sidar_torch.choices.render`, which both layers import)."""

from __future__ import annotations

from ..choices.lenses import LENS_MODELS as _LENS_ROWS, NO_LENS
from ..choices.render import (ANTIALIAS_SAMPLES, AREA_LIGHT_SHADINGS, MAX_SHADOWED_LIGHTS, SHADOW_FILTERS,
                              SHADOW_FRUSTA, TEXTURE_FILTERS)

__all__ = [
    "ANTIALIAS_SAMPLES", "AREA_LIGHT_SHADINGS", "BACKGROUNDS", "GEOMETRY_DTYPES", "LENS_MODELS", "LIGHT_TYPES", "MAX_CAMERA_DISTANCE", "MAX_GL_SIZE",
    "MAX_LIGHT_INTENSITY", "MAX_LIGHT_LEVEL", "MAX_SAMPLE_BYTES", "MAX_SCENE_EXTENT", "MAX_SHADOWED_LIGHTS", "MAX_VIEWS", "MAX_WORKERS", "MESH_DETAILS",
    "OCCLUDER_MATERIALS", "OCCLUDER_SHAPES", "ON_BAD_IMAGE", "SHADOW_FILTERS", "SHADOW_FRUSTA", "SPOT_FALLOFFS",
    "TEXTURE_FILTERS",
]

# The kinds' own tables are ``sidar_torch.scene``'s (``LIGHT_KINDS``, ``SHAPES``, ``MATERIAL_KINDS``, keyed by
# these names). Config is the floor under scene and cannot import them (``scene.kinds`` imports config),
# so the names the fields accept are written here once; ``tests/scene/test_scene.py`` checks that they
# are the tables' keys (and the renderer's meshes').
LIGHT_EMITTERS = {"spot": None, "point": None, "area": "area_light_samples"}
"""Light kind -> the config field that sets how many emitters a light of that kind has (None: one)."""
LIGHT_TYPES = tuple(LIGHT_EMITTERS)
OCCLUDER_SHAPES = ("sphere", "cube", "cylinder", "cone", "torus", "capsule", "icosahedron", "hull", "prism")
OCCLUDER_MATERIALS = ("diffuse", "glossy", "metallic", "transparent", "glass", "principled")
ON_BAD_IMAGE = ("raise", "skip")
BACKGROUNDS = ("black", "view", "sequence")
MESH_DETAILS = ("fixed", "auto")
SPOT_FALLOFFS = ("quadratic", "blender")
GEOMETRY_DTYPES = ("float32", "float64")
LENS_MODELS = (NO_LENS, *_LENS_ROWS)
"""``lens_model`` values: no lens, then the rows of ``sidar_torch.choices.lenses.LENS_MODELS``."""


MAX_GL_SIZE = 16384
"""Largest side, in pixels or texels, of the views and shadow maps the renderer can allocate: Mesa's
llvmpipe (OSMesa and EGL, Mesa 22.3) reports ``GL_MAX_TEXTURE_SIZE = GL_MAX_RENDERBUFFER_SIZE =
16384`` (``GL_MAX_VIEWPORT_DIMS`` is 16384 x 16384 too). GPU drivers report the same or more; the
bound is checked when the config is made, so a larger size fails there, naming the field, rather
than inside OpenGL at the first render."""

MAX_CAMERA_DISTANCE = 1e5
"""Largest ``camera_xy`` and ``camera_height``, painting units. Cameras this far (the box may be far
wider than the cameras reach when ``max_tilt_deg`` limits them: ``tests/test_hard_cases.py`` draws
from ``camera_xy=1e5`` at a tilt of 89.99 degrees) still render (``tests/config/test_config_bounds.py``
renders every bound) and give finite homographies, within 2e-7 px of the analytic ones for views
from that far up and 1e-3 px for the grazing extreme (height 1e-3, a 1 degree field of view;
measured with ``sidar_torch.sample.sequence_homographies``); from about 1e10 the fit loses accuracy
(1e-2 px at 1e12) and at 1e20 it is NaN."""

MAX_SCENE_EXTENT = 100.0
"""Largest position, height and size of a light or an occluder (``light_xy``, ``light_height``,
``area_light_size``, ``occluder_xy``, ``occluder_height``, ``occluder_size``), painting units: 50
times the paper's farthest light (15 / 7). They act on the painting only from nearby: the
transmittance maps store a light's distances in float16, resolving about ``d / 1024`` (0.1 units at
100), and a light's cone and an occluder's shadow are fitted to the painting, so farther values draw
nothing new. The bound also keeps every number of the scene finite (``1e307`` spun forever in
``sidar_torch.scene``, ``1e308`` overflowed)."""

MAX_LIGHT_LEVEL = 1e4
"""Largest light level (``*_irradiance`` and ``ambient``, the renderer's linear units): a white
diffuse painting saturates at about 3.3 and the darkest non-black 8-bit sRGB texel (linear
``1 / 255 / 12.92``) at about 1e4 times less light than white, so beyond this every lit texel is
white."""

MAX_LIGHT_INTENSITY = MAX_LIGHT_LEVEL * 3 * MAX_SCENE_EXTENT**2
"""Largest light intensity (``*_intensity``, irradiance at one painting unit): what gives
:data:`MAX_LIGHT_LEVEL` at the farthest a light can be (``sqrt(3)`` :data:`MAX_SCENE_EXTENT`)."""

MAX_VIEWS = 256
"""Largest ``n_views``: a sample's homographies and their accuracy check cost about 32 KiB per
ordered pair of views (``config.memory``), 2 GiB at 256 views, within :data:`MAX_SAMPLE_BYTES` with
room for the views themselves."""

MAX_SAMPLE_BYTES = 2**32
"""Memory one sample may need (4 GiB), by the estimate of
:func:`sidar_torch.config.memory.estimated_sample_bytes` (views, masks, label, the renderer's
buffers and shadow maps, the homographies): a config over it is refused when it is made, naming
``image_size`` and ``n_views``, instead of failing (or being killed) minutes into the first sample.
The default preset needs about 0.2 GiB."""

MAX_WORKERS = 256
"""Most render processes one call may start (``SidarAugment``'s ``num_workers``, the render pool's,
``export``'s ``workers``). Each is a forked process that renders on one CPU thread (llvmpipe,
``LP_NUM_THREADS=0``) with its own renderer: about 100 MiB of memory of its own once it has
rendered a 3-view 384x512 sample (``/proc/<pid>/smaps_rollup``, private dirty 91-108 MiB), so 256
take about 25 GiB and need 256 hardware threads to render at once, more than a single machine
usually has. A larger count is a mistake (a sample count for a worker count) that would fork until
memory or the process limit ran out; it is refused, naming the argument."""
