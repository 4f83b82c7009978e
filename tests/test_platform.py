"""Platforms: the renderer's own framebuffer gives the pixels OSMesa's buffer gave."""

import numpy as np
import pytest
from OpenGL import GL

from sidar_torch.render import SceneRenderer, renderer
from sidar_torch.render.context import GL_PLATFORM
from sidar_torch.scene import sample_sequence

from conftest import SMALL, small_config, textured_painting

SEQUENCES = [("misaligned", 0), ("paper_misaligned", 1)]
"""(preset, seed) pairs: lit views with shadows, masks, glossy and transparent occluders."""


class OSMesaOwnBuffer:
    """Stand-in for ``framebuffer.Framebuffer`` that draws as pyrender does by default: upright,
    into OSMesa's own buffer (framebuffer 0), read from its front buffer bottom row first."""

    def __init__(self, height, width):
        self.height, self.width = height, width

    def begin_drawing(self):
        GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, 0)

    def end_drawing(self):
        GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, 0)
        GL.glReadBuffer(GL.GL_FRONT)
        GL.glPixelStorei(GL.GL_PACK_ALIGNMENT, 1)
        pixels = GL.glReadPixels(0, 0, self.width, self.height, GL.GL_RGBA, GL.GL_UNSIGNED_BYTE)
        return np.frombuffer(pixels, np.uint8).reshape(self.height, self.width, 4)[::-1].copy()


@pytest.mark.skipif(GL_PLATFORM != "osmesa", reason="framebuffer 0 exists on OSMesa only")
def test_own_framebuffer_gives_the_pixels_of_osmesas_buffer(monkeypatch):
    # The renderer draws upside down into its framebuffer, as Mesa draws into OSMesa's buffer;
    # drawn upright, lit pixels round differently.
    sequences = [(sample_sequence(small_config(p), np.random.default_rng(s)), textured_painting(SMALL, s))
                 for p, s in SEQUENCES]
    ours = SceneRenderer(SMALL)
    theirs = SceneRenderer(SMALL)
    theirs._gl._target = OSMesaOwnBuffer(*SMALL)
    for seq, painting in sequences:
        expected = ours.render(seq, painting)
        with monkeypatch.context() as patch:
            patch.setattr(renderer, "FLIP_Y", np.eye(4))
            got = theirs.render(seq, painting)
        for name in ("views", "masks", "label"):
            assert np.array_equal(getattr(got, name), getattr(expected, name)), name
