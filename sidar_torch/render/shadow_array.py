"""The spot lights' shadow maps of one GL context: the layers of one depth-compare texture array.

The lit shader reads spot light ``k``'s map as layer ``spot_lights[k].shadow_layer`` of one
``sampler2DArrayShadow`` (``programs``, quirk 3), so every map is on one texture unit and
the layer is a texture coordinate. pyrender gives each light its own ``sampler2D``: the shader's
light loop then picks a sampler by a run-time index, which llvmpipe compiles to a switch over
every sampler of the array at every lookup, and the renderer had to bind a map to every one of
the array's samplers (used or not) for every primitive, to keep the layout of bound textures
(and so llvmpipe's shader variant) the same in every draw.

Clearing a map whole costs more than drawing its casters (about 1 ms per 1024^2 layer on llvmpipe),
while they cover a small part of it: each layer remembers the texel rectangle its last draw may have
written (``render.visibility.map_texel_box``), and the next draw clears only that; every other texel
still holds the cleared depth. A texel outside the rectangle was not written, so the map is the
same, texel for texel, as one cleared whole (``tests/render/test_skips.py`` compares the renders).
"""

from __future__ import annotations

from OpenGL import GL

__all__ = ["ShadowMapArray", "TexelBox"]

TexelBox = tuple[int, int, int, int]
"""``(x0, y0, x1, y1)``: texel columns ``x0 .. x1 - 1`` and rows ``y0 .. y1 - 1`` of a map."""


def clear_box(box: TexelBox, offset: tuple[int, int], bits: int) -> int:
    """``glClear(bits)`` of the bound draw framebuffer, limited to ``box`` moved by ``offset``
    (texels); nothing for an empty box. Leaves the scissor test off; returns the texels cleared."""
    x0, y0, x1, y1 = box
    if x0 < x1 and y0 < y1:
        GL.glEnable(GL.GL_SCISSOR_TEST)
        GL.glScissor(offset[0] + x0, offset[1] + y0, x1 - x0, y1 - y0)
        GL.glClear(bits)
    GL.glDisable(GL.GL_SCISSOR_TEST)
    return max(0, x1 - x0) * max(0, y1 - y0)


class ShadowMapArray:
    """Square depth maps, one per layer, read with hardware depth compare and bilinear filtering.

    Args:
        size: side of each map, texels (a power of two).

    The lit shader reads it as ``sampler2DArrayShadow`` (bound by :meth:`bind`).
    """

    def __init__(self, size: int):
        self.size = size
        self.layers = 0
        self._written: list[TexelBox] = []  # per layer: what its last draw may have written
        self.cleared_texels = 0  # so far (for tests and benchmarks)
        self._texture = int(GL.glGenTextures(1))
        GL.glBindTexture(GL.GL_TEXTURE_2D_ARRAY, self._texture)
        for parameter, value in ((GL.GL_TEXTURE_MIN_FILTER, GL.GL_LINEAR), (GL.GL_TEXTURE_MAG_FILTER, GL.GL_LINEAR),
                                 (GL.GL_TEXTURE_WRAP_S, GL.GL_CLAMP_TO_EDGE), (GL.GL_TEXTURE_WRAP_T, GL.GL_CLAMP_TO_EDGE),
                                 (GL.GL_TEXTURE_COMPARE_MODE, GL.GL_COMPARE_REF_TO_TEXTURE),
                                 (GL.GL_TEXTURE_COMPARE_FUNC, GL.GL_LEQUAL)):
            GL.glTexParameteri(GL.GL_TEXTURE_2D_ARRAY, parameter, value)
        GL.glBindTexture(GL.GL_TEXTURE_2D_ARRAY, 0)
        self.reserve(1)  # a complete texture, so every lit draw can bind it

    def bind(self) -> None:
        """Bind the maps' texture to the active texture unit."""
        GL.glBindTexture(GL.GL_TEXTURE_2D_ARRAY, self._texture)

    def reserve(self, layers: int) -> bool:
        """Make room for ``layers`` maps. Growing reallocates the texture, which loses every map's
        texels; returns whether it did."""
        if layers <= self.layers:
            return False
        self.bind()
        GL.glTexImage3D(GL.GL_TEXTURE_2D_ARRAY, 0, GL.GL_DEPTH_COMPONENT, self.size, self.size, layers, 0,
                        GL.GL_DEPTH_COMPONENT, GL.GL_FLOAT, None)
        GL.glBindTexture(GL.GL_TEXTURE_2D_ARRAY, 0)
        self.layers = layers
        self._written = [(0, 0, self.size, self.size)] * layers  # new storage: undefined texels
        return True

    def attach(self, layer: int, writes: TexelBox) -> None:
        """Make map ``layer`` (``0 <= layer < self.layers``) the depth attachment of the bound
        framebuffer and clear it (depth writes must be on), for a draw that writes only texels of
        ``writes`` (the whole map: ``(0, 0, size, size)``)."""
        GL.glFramebufferTextureLayer(GL.GL_FRAMEBUFFER, GL.GL_DEPTH_ATTACHMENT, self._texture, 0, layer)
        self.cleared_texels += clear_box(self._written[layer], (0, 0), GL.GL_DEPTH_BUFFER_BIT)
        self._written[layer] = writes
