"""Configuration: every range and switch of a SIDAR scene, the YAML presets, validation, the schema.

* ``fields``: :class:`SidarConfig`, each field with its meaning (and bounds or choices) as metadata;
  units are in its docstring.
* ``allowed``: the choices of the text fields and the renderer's limits.
* ``numbers``: :func:`as_int` and :func:`as_float`, accepting NumPy and 0-d torch scalars; every
  layer that takes numbers from users can use them.
* ``validation``: coercion and checks, errors naming the field.
* ``loader``: :func:`load_config` and :func:`available_presets`; presets ship in ``presets/``.
* ``schema``: the table of fields ``python -m sidar_torch schema`` prints.
"""

from .allowed import (ANTIALIAS_SAMPLES, BACKGROUNDS, GEOMETRY_DTYPES, LIGHT_TYPES, MAX_GL_SIZE, MAX_SHADOWED_LIGHTS, MESH_DETAILS, OCCLUDER_MATERIALS,
                      OCCLUDER_SHAPES, ON_BAD_IMAGE, SHADOW_FILTERS, SHADOW_FRUSTA, TEXTURE_FILTERS)
from .fields import SidarConfig, field_meaning
from .loader import PRESET_DIR, available_presets, load_config
from .numbers import as_float, as_int

__all__ = [
    "ANTIALIAS_SAMPLES", "BACKGROUNDS", "GEOMETRY_DTYPES", "LIGHT_TYPES", "MAX_GL_SIZE", "MAX_SHADOWED_LIGHTS", "MESH_DETAILS", "OCCLUDER_MATERIALS",
    "OCCLUDER_SHAPES", "ON_BAD_IMAGE", "PRESET_DIR", "SHADOW_FILTERS", "SHADOW_FRUSTA", "TEXTURE_FILTERS",
    "SidarConfig", "as_float", "as_int", "available_presets", "field_meaning", "load_config",
]
