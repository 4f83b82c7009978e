"""A SIDAR scene: plain data (:mod:`.description`), the kinds it is made of as tables (:mod:`.kinds`)
and the pure functions that sample one from a config (:mod:`.sampler`). Nothing here knows OpenGL.
"""

from .description import Camera, Light, Material, Occluder, SceneSequence, ViewScene
from .kinds import LIGHT_KINDS, MATERIAL_KINDS, PAPER_TORUS_SCALE, SHAPES, occluder_radius, spread_beam
from .sampler import CAMERA_CLEARANCE, sample_sequence

__all__ = ["CAMERA_CLEARANCE", "LIGHT_KINDS", "MATERIAL_KINDS", "PAPER_TORUS_SCALE", "SHAPES", "Camera", "Light",
           "Material", "Occluder", "SceneSequence", "ViewScene", "occluder_radius", "sample_sequence", "spread_beam"]
