"""Coloured shadows of transparent occluders: a transmittance map per shadowed spot light.

Opaque occluders go into each shadowed light's depth map (``renderer``); transparent ones
(``alphaMode == "BLEND"``) go instead into that light's tile of one RGBA float16 texture, drawn
from the light's view with the same light matrix:

* **RGB** starts at white and is multiplied (blending ``GL_ZERO, GL_SRC_COLOR``) by the
  transmittance of every transparent caster on the texel's ray,
  ``T = (1 - a_F) * rgb / max(rgb)``: ``rgb`` is the caster's linear base colour, so its hue and
  saturation tint the light while its brightness does not darken it; ``a_F`` is its alpha raised
  towards 1 with the Schlick-Fresnel reflectance at the light's incidence (4 % head-on), as
  ``programs`` raises the opacity the camera sees. Clear glass gives a light, uncoloured shadow,
  coloured glass a tinted one, and alpha -> 1 a black one, like an opaque caster.
* **A** keeps the nearest caster's distance along the light's axis (clip ``w``, painting units;
  blending ``GL_MIN``), so the lookup (``shaders/spot_shadow.glsl``) tints only what lies beyond it.

Only the casters' **back faces** (seen from the light) are drawn: a ray crosses a closed convex
caster once, so its ``T`` applies once, as the camera sees one blended layer of it; and the
stored distance is that of the caster's far side, so its own lit surface is not tinted by itself.
Limits: a surface between two transparent casters gets the product of both; light is neither
refracted nor focused (no caustics); where a ray crosses a non-convex caster (a torus) twice it
is filtered twice, as the camera then sees two layers.

Tiles are ``shadow_map_size / 2`` texels square (bilinear filtering softens the tinted shadow a
little more than the depth map's) and laid out in one ``GL_TEXTURE_2D``: tile ``k`` at column
``k // rows``, row ``k % rows``. One texture unit serves every light. A ``GL_TEXTURE_2D_ARRAY``
would be the natural layout, but with one bound next to the depth-compare samplers, llvmpipe
(Mesa 22.3.6, LLVM 15) crashes in LLVM while compiling the lit shader. Tiles are allocated for
the most shadowed lights a view with a transparent caster has had, and reused. Like the depth maps
(``shadow_array``), a tile is cleared only where its last draw may have written.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Callable

import numpy as np
from OpenGL import GL

from .shadow_array import TexelBox, clear_box

if TYPE_CHECKING:
    from .draws import Surface
    from .programs import Program

__all__ = ["TransmittanceMaps"]

FAR = 60000.0
"""Distance stored where no transparent caster covers a texel (float16 holds up to 65504)."""

class TransmittanceMaps:
    """The transmittance maps of one GL context: tile ``k`` belongs to the view's ``k``-th spot light.

    Args:
        tile: side of each light's map, texels.

    The lit shader reads it as ``sampler2D`` with ``texelFetch`` (bound by :meth:`bind`) and needs
    :attr:`layout`.
    """

    def __init__(self, tile: int):
        self.tile = tile
        self.rows = max(1, int(GL.glGetIntegerv(GL.GL_MAX_TEXTURE_SIZE)) // tile)
        self.tiles = 0
        self._written: list[TexelBox] = []  # per tile: what its last draw may have written
        self.passes = 0  # tiles drawn so far (for tests and benchmarks)
        self.cleared_texels = 0  # so far (for tests and benchmarks)
        self._texture = int(GL.glGenTextures(1))
        self._framebuffer = int(GL.glGenFramebuffers(1))
        self.reserve(1)  # a complete texture, so every lit draw can bind it
        GL.glBindTexture(GL.GL_TEXTURE_2D, self._texture)
        for parameter in (GL.GL_TEXTURE_MIN_FILTER, GL.GL_TEXTURE_MAG_FILTER):
            GL.glTexParameteri(GL.GL_TEXTURE_2D, parameter, GL.GL_NEAREST)  # read by texelFetch
        GL.glBindTexture(GL.GL_TEXTURE_2D, 0)

    @property
    def layout(self) -> tuple[int, int]:
        """``(tile, rows)``: tile side in texels and tiles per column, as the shader reads them."""
        return self.tile, self.rows

    def bind(self) -> None:
        """Bind the tiles' texture to the active texture unit."""
        GL.glBindTexture(GL.GL_TEXTURE_2D, self._texture)

    def reserve(self, tiles: int) -> None:
        """Make room for ``tiles`` tiles (reallocates, losing the contents, only to grow)."""
        if tiles > self.tiles:
            columns = -(-tiles // self.rows)
            GL.glBindTexture(GL.GL_TEXTURE_2D, self._texture)
            GL.glTexImage2D(GL.GL_TEXTURE_2D, 0, GL.GL_RGBA16F, self.tile * columns,
                            self.tile * min(tiles, self.rows), 0, GL.GL_RGBA, GL.GL_FLOAT, None)
            GL.glBindTexture(GL.GL_TEXTURE_2D, 0)
            self.tiles = tiles
            self._written = [(0, 0, self.tile, self.tile)] * tiles  # new storage: undefined texels

    def draw_tile(self, k: int, V: np.ndarray, P: np.ndarray, light_position: np.ndarray,
                  casters: list[Surface], program_for: Callable[[Surface], Program], writes: TexelBox) -> None:
        """Clear tile ``k`` and draw ``casters`` into it from a light.

        Args:
            k: ``0 <= k < self.tiles``.
            V, P: ``(4, 4)`` the light's world-to-camera (OpenGL frame) and projection matrices.
            light_position: ``(3,)`` world position of the light.
            casters: the transparent surfaces (``draws.Surface``); each one's material gives the
                colour and alpha. Drawn in this order (the float16 product rounds in that order).
            program_for: the linked transmittance program for a surface (its vertex layout).
            writes: the tile's texels (tile coordinates) the casters may cover: the next draw
                into the tile clears only these (the whole tile: ``(0, 0, tile, tile)``).
        """
        x, y = self.tile * (k // self.rows), self.tile * (k % self.rows)
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, self._framebuffer)
        GL.glFramebufferTexture2D(GL.GL_FRAMEBUFFER, GL.GL_COLOR_ATTACHMENT0, GL.GL_TEXTURE_2D, self._texture, 0)
        GL.glViewport(x, y, self.tile, self.tile)
        GL.glClearColor(1.0, 1.0, 1.0, FAR)
        self.cleared_texels += clear_box(self._written[k], (x, y), GL.GL_COLOR_BUFFER_BIT)
        self._written[k] = writes
        GL.glScissor(x, y, self.tile, self.tile)
        GL.glEnable(GL.GL_SCISSOR_TEST)
        GL.glDisable(GL.GL_DEPTH_TEST)  # products and minima do not depend on the order
        GL.glEnable(GL.GL_BLEND)
        GL.glBlendEquationSeparate(GL.GL_FUNC_ADD, GL.GL_MIN)
        GL.glBlendFuncSeparate(GL.GL_ZERO, GL.GL_SRC_COLOR, GL.GL_ONE, GL.GL_ONE)
        GL.glEnable(GL.GL_CULL_FACE)
        GL.glCullFace(GL.GL_FRONT)  # back faces only: see the module docstring
        GL.glPolygonMode(GL.GL_FRONT_AND_BACK, GL.GL_FILL)
        for surface in casters:
            program = program_for(surface)
            program.use()
            program.set_uniform("V", V)
            program.set_uniform("P", P)
            program.set_uniform("M", surface.pose)
            program.set_uniform("light_position", light_position)
            program.set_uniform("base_color", surface.material.base_color)
            surface.mesh.draw()
        GL.glUseProgram(0)
        # Leave the state the other passes assume: they set blend functions and culling, never these.
        GL.glBlendEquation(GL.GL_FUNC_ADD)
        GL.glDisable(GL.GL_SCISSOR_TEST)
        GL.glCullFace(GL.GL_BACK)
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, 0)
        GL.glFlush()
        self.passes += 1
