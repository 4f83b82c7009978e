"""What config fields may hold: the choices of the text fields and the limits the renderer imposes (the
renderer's own choices come from :mod:`sidar_torch.render_choices`, which both layers import)."""

from __future__ import annotations

from ..render_choices import ANTIALIAS_SAMPLES, MAX_SHADOWED_LIGHTS, SHADOW_FILTERS, SHADOW_FRUSTA, TEXTURE_FILTERS

__all__ = [
    "ANTIALIAS_SAMPLES", "BACKGROUNDS", "GEOMETRY_DTYPES", "LIGHT_TYPES", "MAX_GL_SIZE", "MAX_SHADOWED_LIGHTS", "MESH_DETAILS", "OCCLUDER_MATERIALS",
    "OCCLUDER_SHAPES", "ON_BAD_IMAGE", "SHADOW_FILTERS", "SHADOW_FRUSTA", "TEXTURE_FILTERS",
]

LIGHT_TYPES = ("spot", "point", "area")
OCCLUDER_SHAPES = ("sphere", "cube", "cylinder", "cone", "torus", "capsule", "icosahedron", "hull", "prism")
OCCLUDER_MATERIALS = ("diffuse", "glossy", "metallic", "transparent", "glass", "principled")
ON_BAD_IMAGE = ("raise", "skip")
BACKGROUNDS = ("black", "view", "sequence")
MESH_DETAILS = ("fixed", "auto")
GEOMETRY_DTYPES = ("float32", "float64")


MAX_GL_SIZE = 16384
"""Largest side, in pixels or texels, of the views and shadow maps the renderer can allocate: Mesa's
llvmpipe (OSMesa and EGL, Mesa 22.3) reports ``GL_MAX_TEXTURE_SIZE = GL_MAX_RENDERBUFFER_SIZE =
16384`` (``GL_MAX_VIEWPORT_DIMS`` is 16384 x 16384 too). GPU drivers report the same or more; the
bound is checked when the config is made, so a larger size fails there, naming the field, rather
than inside OpenGL at the first render."""
