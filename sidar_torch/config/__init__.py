"""Configuration: every range and switch of a SIDAR scene, the YAML presets, validation, the schema.

* ``fields``: :class:`SidarConfig`, each field with its meaning (and bounds or choices) as metadata;
  units are in its docstring.
* ``allowed``: the choices of the text fields, the renderer's limits and the bounds of the number
  fields (``MAX_CAMERA_DISTANCE``, ``MAX_SCENE_EXTENT``, ``MAX_LIGHT_LEVEL``,
  ``MAX_LIGHT_INTENSITY``, ``MAX_VIEWS``, ``MAX_SAMPLE_BYTES``) and of the render processes
  (``MAX_WORKERS``), each with how it was derived.
* ``memory``: :func:`~memory.estimated_sample_bytes`, the memory a sample needs (measured figures).
* ``numbers``: :func:`as_int` and :func:`as_float`, accepting NumPy and 0-d torch scalars (and
  refusing anything else, a ``Fraction`` beyond float's range or a ``Decimal`` included, with a
  ``ValueError`` naming the value); every layer that takes numbers from users can use them.
* ``validation``: coercion and checks against the fields' ``bounds`` and ``choices``, errors
  (``ValueError`` only, a wrong type included) naming the field.
* ``loader``: :func:`load_config` and :func:`available_presets`; presets ship in ``presets/``; every
  error of a YAML file names the file.
* ``files``: reading a user's file safely (a regular file only, opened without blocking, bounded),
  for config files and the export reader.
* ``schema``: the table of fields ``python -m sidar_torch schema`` prints.
"""

from .allowed import (ANTIALIAS_SAMPLES, AREA_LIGHT_SHADINGS, BACKGROUNDS, GEOMETRY_DTYPES, LIGHT_TYPES, MAX_CAMERA_DISTANCE, MAX_GL_SIZE,
                      MAX_LIGHT_INTENSITY, MAX_LIGHT_LEVEL, MAX_SAMPLE_BYTES, MAX_SCENE_EXTENT, MAX_SHADOWED_LIGHTS, MAX_VIEWS, MAX_WORKERS,
                      MESH_DETAILS, OCCLUDER_MATERIALS, OCCLUDER_SHAPES, ON_BAD_IMAGE, SHADOW_FILTERS, SHADOW_FRUSTA, TEXTURE_FILTERS)
from .fields import SidarConfig, field_meaning
from .loader import PRESET_DIR, available_presets, load_config
from .numbers import as_float, as_int

__all__ = [
    "ANTIALIAS_SAMPLES", "AREA_LIGHT_SHADINGS", "BACKGROUNDS", "GEOMETRY_DTYPES", "LIGHT_TYPES", "MAX_CAMERA_DISTANCE", "MAX_GL_SIZE",
    "MAX_LIGHT_INTENSITY", "MAX_LIGHT_LEVEL", "MAX_SAMPLE_BYTES", "MAX_SCENE_EXTENT", "MAX_SHADOWED_LIGHTS", "MAX_VIEWS", "MAX_WORKERS", "MESH_DETAILS",
    "OCCLUDER_MATERIALS", "OCCLUDER_SHAPES", "ON_BAD_IMAGE", "PRESET_DIR", "SHADOW_FILTERS", "SHADOW_FRUSTA",
    "TEXTURE_FILTERS",
    "SidarConfig", "as_float", "as_int", "available_presets", "field_meaning", "load_config",
]
