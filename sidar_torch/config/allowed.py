"""What config fields may hold: the choices of the text fields and the limits the renderer imposes."""

from __future__ import annotations

__all__ = [
    "BACKGROUNDS", "LIGHT_TYPES", "MAX_SHADOWED_LIGHTS", "MESH_DETAILS", "OCCLUDER_MATERIALS",
    "OCCLUDER_SHAPES", "ON_BAD_IMAGE", "SHADOW_FILTERS", "SHADOW_FRUSTA", "TEXTURE_FILTERS",
]

LIGHT_TYPES = ("spot", "point", "area")
OCCLUDER_SHAPES = ("sphere", "cube", "cylinder", "cone", "torus", "capsule", "icosahedron", "hull", "prism")
OCCLUDER_MATERIALS = ("diffuse", "glossy", "metallic", "transparent", "glass", "principled")
ON_BAD_IMAGE = ("raise", "skip")
SHADOW_FILTERS = ("tent", "bilinear")
BACKGROUNDS = ("black", "view", "sequence")
SHADOW_FRUSTA = ("cone", "fitted")
MESH_DETAILS = ("fixed", "auto")
TEXTURE_FILTERS = ("trilinear", "bilinear")

MAX_SHADOWED_LIGHTS = 24
"""Shadow-casting GL lights one view may use (texture units left after pyrender's reserved ones)."""
