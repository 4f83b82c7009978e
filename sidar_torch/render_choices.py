"""What the renderer offers, as plain constants: the choices of its settings and its limits.

Both the configuration (which validates a preset's fields against them) and the render layer
(which implements them) need these names. The layers import only downwards
(config -> geometry -> scene -> render -> ...), and ``render`` may not import ``config``, so the
names live here, under both: this module imports nothing, loads no GL, and ``config`` re-exports
them for users.
"""

__all__ = ["ANTIALIAS_SAMPLES", "MAX_SHADOWED_LIGHTS", "SHADOW_FILTERS", "SHADOW_FRUSTA", "TEXTURE_FILTERS"]

MAX_SHADOWED_LIGHTS = 24
"""Shadow-casting GL lights one view may use (texture units left after pyrender's reserved ones)."""

SHADOW_FILTERS = ("tent", "bilinear")
"""How a shadow-map lookup is filtered (``SidarConfig.shadow_filter``)."""

SHADOW_FRUSTA = ("cone", "fitted")
"""What a spot light's shadow map covers (``SidarConfig.shadow_frustum``)."""

TEXTURE_FILTERS = ("trilinear", "bilinear")
"""How the painting's texture is filtered (``SidarConfig.texture_filter``)."""

ANTIALIAS_SAMPLES = (1, 2, 4, 8)
"""Samples per pixel of a view's colour pass (``SidarConfig.antialias``); the GL context must offer
the count (llvmpipe offers only 4 besides 1), which the renderer checks when it is created."""
