"""The spot lights' shadow maps of one GL context: the layers of one depth-compare texture array.

The lit shader reads spot light ``k``'s map as layer ``spot_lights[k].shadow_layer`` of one
``sampler2DArrayShadow`` (``shader_patches``, quirk 3), so every map is on one texture unit and
the layer is a texture coordinate. pyrender gives each light its own ``sampler2D``: the shader's
light loop then picks a sampler by a run-time index, which llvmpipe compiles to a switch over
every sampler of the array at every lookup, and the renderer had to bind a map to every one of
the array's samplers (used or not) for every primitive, to keep the layout of bound textures
(and so llvmpipe's shader variant) the same in every draw.
"""

from __future__ import annotations

from OpenGL import GL

__all__ = ["ShadowMapArray"]


class ShadowMapArray:
    """Square depth maps, one per layer, read with hardware depth compare and bilinear filtering.

    Args:
        size: side of each map, texels (a power of two).

    Pass an instance to pyrender's texture binding like a texture (it has ``_bind``).
    """

    def __init__(self, size: int):
        self.size = size
        self.layers = 0
        self._texture = int(GL.glGenTextures(1))
        GL.glBindTexture(GL.GL_TEXTURE_2D_ARRAY, self._texture)
        for parameter, value in ((GL.GL_TEXTURE_MIN_FILTER, GL.GL_LINEAR), (GL.GL_TEXTURE_MAG_FILTER, GL.GL_LINEAR),
                                 (GL.GL_TEXTURE_WRAP_S, GL.GL_CLAMP_TO_EDGE), (GL.GL_TEXTURE_WRAP_T, GL.GL_CLAMP_TO_EDGE),
                                 (GL.GL_TEXTURE_COMPARE_MODE, GL.GL_COMPARE_REF_TO_TEXTURE),
                                 (GL.GL_TEXTURE_COMPARE_FUNC, GL.GL_LEQUAL)):
            GL.glTexParameteri(GL.GL_TEXTURE_2D_ARRAY, parameter, value)
        GL.glBindTexture(GL.GL_TEXTURE_2D_ARRAY, 0)
        self.reserve(1)  # a complete texture, so every lit draw can bind it

    def _bind(self) -> None:
        GL.glBindTexture(GL.GL_TEXTURE_2D_ARRAY, self._texture)

    def reserve(self, layers: int) -> bool:
        """Make room for ``layers`` maps. Growing reallocates the texture, which loses every map's
        texels; returns whether it did."""
        if layers <= self.layers:
            return False
        self._bind()
        GL.glTexImage3D(GL.GL_TEXTURE_2D_ARRAY, 0, GL.GL_DEPTH_COMPONENT, self.size, self.size, layers, 0,
                        GL.GL_DEPTH_COMPONENT, GL.GL_FLOAT, None)
        GL.glBindTexture(GL.GL_TEXTURE_2D_ARRAY, 0)
        self.layers = layers
        return True

    def attach(self, layer: int) -> None:
        """Make map ``layer`` (``0 <= layer < self.layers``) the depth attachment of the bound framebuffer."""
        GL.glFramebufferTextureLayer(GL.GL_FRAMEBUFFER, GL.GL_DEPTH_ATTACHMENT, self._texture, 0, layer)
