"""The painting seen in reflective occluders and through glass ones (quirk 8 in ``programs``).

The world is black but for the painting (a textured rectangle in z = 0, facing +z) and the
occluders, so what a ray leaving an occluder's surface meets is the painting or nothing. The lit
shader follows one reflected ray and, for glass, one refracted ray to the plane z = 0 and samples
the painting there (``shaders/painting_mirror.glsl``). Which materials get which program variant
is decided here (:func:`mirror_define`), and what the shader needs about the painting is
:class:`PaintingMirror`, set on the renderer for each view.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry import plane_size
from ..scene import Material
from .gpu import PaintingTexture

__all__ = ["MIRROR_DEFINES", "PaintingMirror", "mirror_define", "painting_diffuse"]

REFLECTION = "PAINTING_REFLECTION"
REFRACTION = "PAINTING_REFRACTION"
MIRROR_DEFINES = (REFLECTION, REFRACTION)
"""The lit shader's program defines of quirk 8 (``programs`` quirk 8)."""


def mirror_define(material: Material) -> str | None:
    """The program variant an occluder of ``material`` is drawn with, or None (the plain program).

    * ``PAINTING_REFRACTION``: a transparent material with ``ior > 1`` (glass): the painting seen
      through it is refracted, and reflected at its surface;
    * ``PAINTING_REFLECTION``: an opaque material with a specular layer (metallic, a specular level
      or a clear coat): the painting is reflected;
    * None: purely diffuse opaque materials (they reflect nothing) and transparent ones without an
      index of refraction, which stay blended over what lies behind them, undisplaced.
    """
    if material.transparent:
        return REFRACTION if material.ior > 1.0 else None
    if material.metallic > 0.0 or material.specular > 0.0 or material.coat > 0.0:
        return REFLECTION
    return None


def painting_diffuse(material: Material) -> float:
    """The factor of the painting's irradiance (over pi) in its radiance, for the painting's
    ``material``: the lit shader's diffuse term at normal incidence, ``0.96 (1 - metallic)`` times
    the light its specular layer (``f0``) and clear coat (4 %) leave, ``(1 - f0) (1 - 0.04 coat)``;
    the painting's own specular highlights are not in what occluders reflect. A painting with
    ``transmission`` ``t`` keeps ``1 - t`` of that diffuse light (as ``scene_graph.transmission_factors``
    draws it)."""
    f0 = material.metallic + (1.0 - material.metallic) * 0.08 * material.specular  # white base colour
    diffuse = 0.96 * (1.0 - material.metallic) * (1.0 - f0) * (1.0 - 0.04 * material.coat)
    return float(diffuse * (1.0 - material.transmission))


@dataclass(frozen=True)
class PaintingMirror:
    """What the lit shader needs about the painting to reflect or refract it in one view.

    Attributes:
        texture: the painting's texture (the plane's base colour, with mipmaps).
        half_size: ``(2,)`` float32 half width and height of the painting, painting units.
        diffuse: :func:`painting_diffuse` of the view's painting material.
    """

    texture: PaintingTexture
    half_size: np.ndarray
    diffuse: float

    @classmethod
    def of_view(cls, texture: PaintingTexture, image_size: tuple[int, int], material: Material) -> "PaintingMirror":
        return cls(texture, np.array(plane_size(image_size), np.float32) / 2, painting_diffuse(material))
