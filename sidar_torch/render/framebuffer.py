"""The renderer's own single-sampled offscreen framebuffer: where every forward pass draws.

Why not the context's default framebuffer (framebuffer 0): a surfaceless or device EGL
context has none (drawing to it is ``GL_INVALID_FRAMEBUFFER_OPERATION``). Why not pyrender's
offscreen framebuffer: it is 4x multisampled, which would blur the label that must equal the
painting bit for bit. So the renderer draws into this one on every platform, and EGL and OSMesa
run one code path.

Forward passes draw into it **upside down** (projection times :data:`FLIP_Y`, clockwise front
faces), so its first row in memory is the image's top row. Mesa draws window-system buffers,
OSMesa's included, the same way, and the rasteriser's arithmetic depends on that orientation:
drawn upright, about 1-3 % of lit pixels come out 1-6 levels different from what OSMesa's own
buffer gave. Drawn upside down, every view, mask and label is byte-identical to rendering into
OSMesa's buffer, and rows need no reversal on readback.

Like every other GL object of a renderer, it is freed with its context (framebuffers and
renderbuffers belong to that context alone); it issues no GL call when collected.
"""

from __future__ import annotations

import numpy as np
from OpenGL import GL

__all__ = ["FLIP_Y", "Framebuffer", "size_limits"]

FLIP_Y = np.diag([1.0, -1.0, 1.0, 1.0])
"""Left-multiplies a projection matrix so that clip-space y, and so the image, is drawn upside down."""


def size_limits() -> tuple[int, int]:
    """``(GL_MAX_RENDERBUFFER_SIZE, GL_MAX_TEXTURE_SIZE)`` of the current context: the largest side,
    in pixels, of a renderbuffer and of a 2-D texture (16384 each on llvmpipe)."""
    return int(GL.glGetIntegerv(GL.GL_MAX_RENDERBUFFER_SIZE)), int(GL.glGetIntegerv(GL.GL_MAX_TEXTURE_SIZE))


class Framebuffer:
    """An RGBA8 colour renderbuffer and a 24-bit depth renderbuffer of ``width`` x ``height``
    pixels, single-sampled, in the current context.

    Raises:
        RuntimeError: the driver reports the framebuffer incomplete.
    """

    def __init__(self, width: int, height: int):
        self.width, self.height = width, height
        self.id = GL.glGenFramebuffers(1)
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, self.id)
        for attachment, storage in ((GL.GL_COLOR_ATTACHMENT0, GL.GL_RGBA8),
                                    (GL.GL_DEPTH_ATTACHMENT, GL.GL_DEPTH_COMPONENT24)):
            renderbuffer = GL.glGenRenderbuffers(1)
            GL.glBindRenderbuffer(GL.GL_RENDERBUFFER, renderbuffer)
            GL.glRenderbufferStorage(GL.GL_RENDERBUFFER, storage, width, height)
            GL.glFramebufferRenderbuffer(GL.GL_FRAMEBUFFER, attachment, GL.GL_RENDERBUFFER, renderbuffer)
        status = GL.glCheckFramebufferStatus(GL.GL_FRAMEBUFFER)
        GL.glBindRenderbuffer(GL.GL_RENDERBUFFER, 0)
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, 0)
        if status != GL.GL_FRAMEBUFFER_COMPLETE:
            raise RuntimeError(f"offscreen framebuffer {width} x {height} incomplete (status 0x{int(status):04x})")

    def begin_drawing(self) -> None:
        """Make it the draw framebuffer, with clockwise front faces: the winding a projection
        flipped by :data:`FLIP_Y` gives counter-clockwise triangles."""
        GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, self.id)
        GL.glFrontFace(GL.GL_CW)

    def end_drawing(self) -> np.ndarray:
        """Restore counter-clockwise front faces (shadow passes cull with them) and return the
        colour buffer as ``(height, width, 4)`` uint8, top row first."""
        GL.glFrontFace(GL.GL_CCW)
        GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, self.id)
        GL.glReadBuffer(GL.GL_COLOR_ATTACHMENT0)
        GL.glPixelStorei(GL.GL_PACK_ALIGNMENT, 1)
        pixels = GL.glReadPixels(0, 0, self.width, self.height, GL.GL_RGBA, GL.GL_UNSIGNED_BYTE)
        return np.frombuffer(pixels, dtype=np.uint8).reshape(self.height, self.width, 4).copy()
