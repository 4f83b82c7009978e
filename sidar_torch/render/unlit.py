"""The unlit draws: the label (the painting as the reference camera sees it) and each view's
opacity (the fraction of the painting hidden at each pixel). Both are the unlit pass of
``render.passes`` (``UnlitPass``), whose ``shaders/unlit.frag`` outputs the lit draw's Fresnel opacity (``programs`` quirk 5).
"""

from __future__ import annotations

import numpy as np

from ..scene import Camera, Material
from ..timing import timed
from .draws import Surface, ViewDraws
from .gpu import GpuMesh, PaintingTexture
from .passes import Passes, UnlitPass
from .scene_graph import gl_material, view_draws

__all__ = ["render_label", "render_opacity"]


def render_label(passes: Passes, camera: Camera, painting: GpuMesh, texture: PaintingTexture,
                 image_size: tuple[int, int]) -> np.ndarray:
    """The label: ``(H, W, 3)`` uint8, the ``painting`` mesh with its ``texture`` as ``camera`` sees
    it, unlit (white, opaque), with nothing else in the scene."""
    plain = Material(np.ones(4), 0.0, 1.0)
    with timed("graph"):
        draws = view_draws(camera, 1.0, painting, plain, texture, image_size)
    return passes.draw(draws, UnlitPass("label"), [draws.painting])[..., :3]


def render_opacity(passes: Passes, draws: ViewDraws, visible: list[Surface], mask: np.ndarray) -> np.ndarray:
    """The view's opacity: ``(H, W)`` uint8, 255 times the fraction of the painting hidden.

    That is 255 outside the painting (background) and behind opaque occluders, 0 where the
    painting is seen unobstructed, and ``255 (1 - prod_k (1 - a_k))`` where transparent
    occluders ``k`` cover it, ``a_k`` being the opacity the colour draw blends them with: the
    material's alpha raised towards 1 by the Schlick-Fresnel reflectance of the view (4 % at
    normal incidence, all at grazing angles; ``programs`` quirk 5). The colour draw also makes
    a transparent occluder more opaque under its specular highlights; that light-dependent part
    is left out here (it would need a lit draw), so under a highlight the value is lower.

    An unlit draw of the view the colour draw drew, its materials replaced: the painting white and
    opaque, the ``visible`` occluders black with their alpha and blend mode, so each transparent
    layer multiplies what shows of the painting by ``1 - a_k`` whatever the order, and an opaque one
    zeroes it. The pass sorts and depth-tests the occluders as in the colour draw (a transparent surface hides transparent
    surfaces behind it drawn later, as it does there), and occluder parts behind the painting
    fail the depth test. The framebuffer holds 8 bits, rounded after each blended layer: within
    1/255 of the exact value per transparent layer.

    With no visible occluder the draw would give the painting's coverage, which the ``mask``
    (``(H, W)`` bool, True off the painting) already is, so it is skipped.
    """
    if not visible:
        return mask.astype(np.uint8) * 255
    with timed("graph"):
        white = Surface(draws.painting.mesh, draws.painting.pose, gl_material(Material(np.ones(4), 0.0, 1.0)))
        black = [Surface(s.mesh, s.pose, gl_material(Material(np.array([0.0, 0.0, 0.0, s.material.base_color[3]]), 0.0, 1.0)))
                 for s in visible]
    shown = passes.draw(draws, UnlitPass("opacity"), [white, *black])
    return 255 - shown[..., 0]
