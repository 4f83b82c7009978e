"""What the renderer offers, as plain constants: the choices of its settings and its limits.

Both the configuration (which validates a preset's fields against them) and the render layer
(which implements them) need these names, and ``render`` may not import ``config``, so they live on
the floor under both (``sidar_torch.choices``): this module imports nothing, loads no GL, and
``config`` re-exports them for users.
"""

__all__ = ["ANTIALIAS_SAMPLES", "AREA_LIGHT_SHADINGS", "AUTO_MAP_SIZE", "MAX_AUTO_MAP_SIZE", "MAX_SHADOWED_LIGHTS", "MIN_AUTO_MAP_SIZE",
           "SHADOW_FILTERS", "SHADOW_FRUSTA", "TEXTURE_FILTERS", "shadow_map_side"]

MAX_SHADOWED_LIGHTS = 24
"""Shadow-casting spot lights one view may use: the length of the lights' uniform block (``render.light_block``)."""

AREA_LIGHT_SHADINGS = ("per_light", "per_emitter")
"""How often an area light's shading is evaluated at a fragment (``SidarConfig.area_light_shading``)."""

SHADOW_FILTERS = ("tent", "bilinear")
"""How a shadow-map lookup is filtered (``SidarConfig.shadow_filter``)."""

SHADOW_FRUSTA = ("cone", "fitted")
"""What a spot light's shadow map covers (``SidarConfig.shadow_frustum``)."""

TEXTURE_FILTERS = ("trilinear", "bilinear", "supersampled")
"""How the painting's texture is filtered (``SidarConfig.texture_filter``)."""

AUTO_MAP_SIZE = "auto"
"""``SidarConfig.shadow_map_size`` value that ties the map's side to the output (:func:`shadow_map_side`)."""

MIN_AUTO_MAP_SIZE, MAX_AUTO_MAP_SIZE = 512, 2048
"""The sides ``"auto"`` keeps to: below 512 the sweep's error grows fast (``docs/speed.md``); above 2048 a
view's maps (up to 24, 6 bytes per texel) would take gigabytes."""


def shadow_map_side(size: int | str, image_size: tuple[int, int]) -> int:
    """The side, in texels, of each shadow map for a ``shadow_map_size`` setting.

    ``"auto"`` gives about one map texel per pixel across a fitted frustum (which spans about what
    the camera sees): the smallest power of two at least the image's longer side, within
    :data:`MIN_AUTO_MAP_SIZE` and :data:`MAX_AUTO_MAP_SIZE` (512 at 192 x 256 and 384 x 512, 1024 at
    768 x 1024).

    Args:
        size: a power of two (returned as is) or ``"auto"``.
        image_size: ``(H, W)``, pixels.
    """
    if size != AUTO_MAP_SIZE:
        return size
    return min(MAX_AUTO_MAP_SIZE, max(MIN_AUTO_MAP_SIZE, 1 << (max(image_size) - 1).bit_length()))


ANTIALIAS_SAMPLES = (1, 2, 4, 8)
"""Samples per pixel of a view's colour pass (``SidarConfig.antialias``); the GL context must offer
the count (llvmpipe offers only 4 besides 1), which the renderer checks when it is created."""
