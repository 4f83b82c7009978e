"""The renderer's own offscreen framebuffer: where every forward pass draws.

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
OSMesa's buffer (but for the painting seen in mirrors and glass, whose texture level comes from
screen-space derivatives taken per 2 x 2 quad: a few of its pixels move by one level), and rows need
no reversal on readback.

With ``samples > 1`` (config ``antialias``) it also holds a multisampled colour and depth pair of
the same size. A pass drawn inside :meth:`Framebuffer.multisampled` (the lit colour pass) draws
into that pair, and :meth:`Framebuffer.end_drawing` resolves it into the single-sampled colour
buffer (``glBlitFramebuffer``, the average of each pixel's samples) before reading back. Every other
pass (masks, opacity, label) draws single-sampled, exactly as without antialiasing.

With ``outputs = 2`` (``shadow_free``) each buffer has a second colour attachment: a pass begun with
two outputs writes its fragment shader's ``location = 1`` output there (the shadow-free colour,
``programs`` quirk 10), and :meth:`Framebuffer.end_drawing` resolves and reads both.

The single-sampled buffers have a stencil: the lit colour pass can leave in it which pixels show
the painting (:meth:`Framebuffer.read_stencil`), from which the renderer takes the mask.

Its size is the size passes draw and read (:meth:`Framebuffer.resize`, a render's canvas:
``render.canvas``); its storage only grows, to the largest size asked so far, and a smaller size is
drawn into the storage's first rows and columns (the viewport, and clears scissored to it): the
rasteriser's arithmetic depends on window coordinates only, so the bytes are those of a framebuffer
of exactly that size (``tests/render/test_canvas.py``).

Like every other GL object of a renderer, it is freed with its context (framebuffers and
renderbuffers belong to that context alone); it issues no GL call when collected, only when its
storage grows (the old renderbuffers are deleted then).
"""

from __future__ import annotations

import contextlib
from typing import Iterator

import numpy as np
from OpenGL import GL

__all__ = ["FLIP_Y", "FloatFramebuffer", "Framebuffer", "LevelsFramebuffer", "sample_counts", "size_limits"]

FLIP_Y = np.diag([1.0, -1.0, 1.0, 1.0])
"""Left-multiplies a projection matrix so that clip-space y, and so the image, is drawn upside down."""


def size_limits() -> tuple[int, int]:
    """``(GL_MAX_RENDERBUFFER_SIZE, GL_MAX_TEXTURE_SIZE)`` of the current context: the largest side,
    in pixels, of a renderbuffer and of a 2-D texture (16384 each on llvmpipe)."""
    return int(GL.glGetIntegerv(GL.GL_MAX_RENDERBUFFER_SIZE)), int(GL.glGetIntegerv(GL.GL_MAX_TEXTURE_SIZE))


def sample_counts() -> tuple[int, ...]:
    """The sample counts above 1 the current context offers for an RGBA8 renderbuffer, largest
    first (``glGetInternalformativ``; llvmpipe offers only 4). A driver may silently round another
    count up to one of these, so the renderer accepts only these."""
    n = int(np.ravel(GL.glGetInternalformativ(GL.GL_RENDERBUFFER, GL.GL_RGBA8, GL.GL_NUM_SAMPLE_COUNTS, 1))[0])
    if n == 0:
        return ()
    return tuple(int(c) for c in np.ravel(GL.glGetInternalformativ(GL.GL_RENDERBUFFER, GL.GL_RGBA8, GL.GL_SAMPLES, n)))


_COLOURS = (GL.GL_COLOR_ATTACHMENT0, GL.GL_COLOR_ATTACHMENT1, GL.GL_COLOR_ATTACHMENT2)
"""The colour attachments of an output count's framebuffers, in output (``location``) order."""


def _new_framebuffer(width: int, height: int, samples: int, outputs: int, colour: int = GL.GL_RGBA8,
                     depth: bool = True) -> tuple[int, list[int]]:
    """A framebuffer with ``outputs`` colour renderbuffers of format ``colour`` (RGBA8, or a float format
    for the camera pass, an integer one for the lens's resampling) and, with ``depth``, a 24-bit depth,
    8-bit stencil renderbuffer, ``samples`` per pixel (1: single-sampled), and its renderbuffers. Raises
    RuntimeError if the driver reports it incomplete."""
    framebuffer = GL.glGenFramebuffers(1)
    GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, framebuffer)
    renderbuffers = []
    attachments = [(c, colour) for c in _COLOURS[:outputs]]
    if depth:
        attachments.append((GL.GL_DEPTH_STENCIL_ATTACHMENT, GL.GL_DEPTH24_STENCIL8))
    for attachment, storage in attachments:
        renderbuffer = GL.glGenRenderbuffers(1)
        renderbuffers.append(int(renderbuffer))
        GL.glBindRenderbuffer(GL.GL_RENDERBUFFER, renderbuffer)
        if samples > 1:
            GL.glRenderbufferStorageMultisample(GL.GL_RENDERBUFFER, samples, storage, width, height)
        else:
            GL.glRenderbufferStorage(GL.GL_RENDERBUFFER, storage, width, height)
        GL.glFramebufferRenderbuffer(GL.GL_FRAMEBUFFER, attachment, GL.GL_RENDERBUFFER, renderbuffer)
    status = GL.glCheckFramebufferStatus(GL.GL_FRAMEBUFFER)
    GL.glBindRenderbuffer(GL.GL_RENDERBUFFER, 0)
    GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, 0)
    if status != GL.GL_FRAMEBUFFER_COMPLETE:
        raise RuntimeError(f"offscreen framebuffer {width} x {height}, {samples} sample(s), incomplete "
                           f"(status 0x{int(status):04x})")
    return framebuffer, renderbuffers


def _delete_framebuffer(framebuffer: int, renderbuffers: list[int]) -> None:
    GL.glDeleteFramebuffers(1, [framebuffer])
    GL.glDeleteRenderbuffers(len(renderbuffers), renderbuffers)


class _Storage:
    """The GL objects behind a framebuffer of a drawing size that may change: made at ``capacity``
    (width, height), remade larger when a size beyond it is asked (:meth:`fit`)."""

    def __init__(self, make, width: int, height: int):
        self._make = make  # (width, height) -> [(framebuffer, renderbuffers), ...]
        self.capacity = (width, height)
        self.objects = make(width, height)

    def fit(self, width: int, height: int) -> bool:
        """Grow to hold ``width`` x ``height`` (each side to at least the larger of the old and the
        asked); whether it was remade."""
        if width <= self.capacity[0] and height <= self.capacity[1]:
            return False
        for framebuffer, renderbuffers in self.objects:
            _delete_framebuffer(framebuffer, renderbuffers)
        self.capacity = (max(width, self.capacity[0]), max(height, self.capacity[1]))
        self.objects = self._make(*self.capacity)
        return True


def clear_drawn(bits: int, width: int, height: int, capacity: tuple[int, int]) -> None:
    """``glClear(bits)`` of the bound draw framebuffer, only its first ``width`` x ``height`` pixels when
    its storage (``capacity``) is larger: what a pass draws and reads; the rest is never read."""
    if (width, height) == tuple(capacity):
        GL.glClear(bits)
        return
    GL.glScissor(0, 0, width, height)
    GL.glEnable(GL.GL_SCISSOR_TEST)
    GL.glClear(bits)
    GL.glDisable(GL.GL_SCISSOR_TEST)


class Framebuffer:
    """An RGBA8 colour renderbuffer (two with ``outputs = 2``) and a depth and stencil renderbuffer of
    ``width`` x ``height`` pixels, single-sampled, in the current context; with ``samples > 1``
    also a multisampled set for the passes drawn inside :meth:`multisampled`. ``width`` and ``height``
    are the size drawn and read, which :meth:`resize` changes.

    Raises:
        ValueError: ``samples`` is neither 1 nor a count of :func:`sample_counts` (naming the
            config field ``antialias``); ``outputs`` is not 1 or 2.
        RuntimeError: the driver reports a framebuffer incomplete.
    """

    def __init__(self, width: int, height: int, samples: int = 1, outputs: int = 1):
        if outputs not in (1, 2):
            raise ValueError(f"outputs: expected 1 or 2 colour outputs, got {outputs!r}")
        self.width, self.height, self.samples, self.outputs = width, height, samples, outputs
        if samples != 1 and samples not in sample_counts():
            raise ValueError(f"antialias: {samples} samples per pixel is not offered by this OpenGL context "
                             f"(GL_MAX_SAMPLES = {int(GL.glGetIntegerv(GL.GL_MAX_SAMPLES))}): expected 1 or one of "
                             f"{sample_counts()}")
        self._storage = _Storage(self._make, width, height)
        self._multisample = False
        self._drawing = 1  # colour outputs of the pass being drawn

    def _make(self, width: int, height: int) -> list[tuple[int, list[int]]]:
        single = _new_framebuffer(width, height, 1, self.outputs)
        return [single, _new_framebuffer(width, height, self.samples, self.outputs)] if self.samples > 1 else [single]

    @property
    def id(self) -> int:
        """The single-sampled framebuffer's GL name."""
        return self._storage.objects[0][0]

    @property
    def _multisampled_id(self) -> int | None:
        return self._storage.objects[1][0] if self.samples > 1 else None

    @property
    def capacity(self) -> tuple[int, int]:
        """``(width, height)`` of the storage: the largest size drawn so far, per side."""
        return self._storage.capacity

    def resize(self, width: int, height: int) -> None:
        """Draw and read ``width`` x ``height`` pixels from now on (the storage grows if it must)."""
        self._storage.fit(width, height)
        self.width, self.height = width, height

    def clear(self, bits: int) -> None:
        """Clear ``bits`` of the drawn ``width`` x ``height`` pixels (:func:`clear_drawn`); bound by
        :meth:`begin_drawing` first."""
        clear_drawn(bits, self.width, self.height, self.capacity)

    @contextlib.contextmanager
    def multisampled(self) -> Iterator[None]:
        """Passes drawn in this block draw into the multisampled buffers (if ``samples > 1``; else
        nothing changes); :meth:`end_drawing` resolves them."""
        self._multisample = self._multisampled_id is not None
        try:
            yield
        finally:
            self._multisample = False

    def begin_drawing(self, outputs: int = 1) -> None:
        """Make it the draw framebuffer, drawing the fragment shader's first ``outputs`` colour
        outputs (at most :attr:`outputs`), with clockwise front faces: the winding a projection
        flipped by :data:`FLIP_Y` gives counter-clockwise triangles."""
        if not 1 <= outputs <= self.outputs:
            raise ValueError(f"outputs: this framebuffer has {self.outputs} colour output(s), a pass asked for {outputs}")
        GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, self._multisampled_id if self._multisample else self.id)
        GL.glDrawBuffers(outputs, _COLOURS[:outputs])
        GL.glFrontFace(GL.GL_CW)
        self._drawing = outputs

    def end_drawing(self) -> np.ndarray:
        """Restore counter-clockwise front faces (shadow passes cull with them), resolve a
        multisampled pass into the single-sampled colour buffers, and return the pass's outputs as
        ``(outputs, height, width, 4)`` uint8, top row first (``outputs`` of :meth:`begin_drawing`)."""
        GL.glFrontFace(GL.GL_CCW)
        GL.glPixelStorei(GL.GL_PACK_ALIGNMENT, 1)
        images = np.empty((self._drawing, self.height, self.width, 4), np.uint8)
        for k, attachment in enumerate(_COLOURS[:self._drawing]):
            if self._multisample:
                GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, self._multisampled_id)
                GL.glReadBuffer(attachment)
                GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, self.id)
                GL.glDrawBuffers(1, [attachment])
                GL.glBlitFramebuffer(0, 0, self.width, self.height, 0, 0, self.width, self.height,
                                     GL.GL_COLOR_BUFFER_BIT, GL.GL_NEAREST)
            GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, self.id)
            GL.glReadBuffer(attachment)
            pixels = GL.glReadPixels(0, 0, self.width, self.height, GL.GL_RGBA, GL.GL_UNSIGNED_BYTE)
            images[k] = np.frombuffer(pixels, dtype=np.uint8).reshape(self.height, self.width, 4)
        return images

    def read_stencil(self) -> np.ndarray:
        """``(height, width)`` uint8: the single-sampled stencil buffer, top row first, as the last
        pass drawn into it left it."""
        GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, self.id)
        GL.glPixelStorei(GL.GL_PACK_ALIGNMENT, 1)
        pixels = GL.glReadPixels(0, 0, self.width, self.height, GL.GL_STENCIL_INDEX, GL.GL_UNSIGNED_BYTE)
        return np.frombuffer(pixels, dtype=np.uint8).reshape(self.height, self.width)


class FloatFramebuffer:
    """A single-sampled float colour renderbuffer (R32F for one channel, RGBA32F for three: RGB32F need
    not be renderable) and a depth and stencil one for the depth test, of ``width`` x ``height`` pixels:
    the camera pass (``Passes.camera_frame``) writes each pixel's value into it, in float32, drawn upside
    down like every pass (the lens's resampling sources, ``render.resample``, upright).

    Raises:
        RuntimeError: the driver reports it incomplete.
    """

    _FORMATS = {1: (GL.GL_R32F, GL.GL_RED), 3: (GL.GL_RGBA32F, GL.GL_RGB)}
    """channels -> (renderbuffer format, read-back format)."""

    def __init__(self, width: int, height: int, channels: int = 1):
        self.width, self.height, self.channels = width, height, channels
        storage, self._read = self._FORMATS[channels]
        self._storage = _Storage(lambda w, h: [_new_framebuffer(w, h, 1, 1, storage)], width, height)

    @property
    def id(self) -> int:
        """The framebuffer's GL name."""
        return self._storage.objects[0][0]

    def resize(self, width: int, height: int) -> None:
        """Draw and read ``width`` x ``height`` pixels from now on (see :meth:`Framebuffer.resize`)."""
        self._storage.fit(width, height)
        self.width, self.height = width, height

    def clear(self, bits: int) -> None:
        """Clear ``bits`` of the drawn pixels (:func:`clear_drawn`); bound by :meth:`begin_drawing` first."""
        clear_drawn(bits, self.width, self.height, self._storage.capacity)

    def begin_drawing(self) -> None:
        """Make it the draw framebuffer, with clockwise front faces (see :meth:`Framebuffer.begin_drawing`)."""
        GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, self.id)
        GL.glDrawBuffers(1, _COLOURS[:1])
        GL.glFrontFace(GL.GL_CW)

    def end_drawing(self) -> np.ndarray:
        """Restore counter-clockwise front faces and return the first ``channels`` channels: ``(height,
        width)`` (one) or ``(height, width, channels)`` float32, the first row drawn first."""
        GL.glFrontFace(GL.GL_CCW)
        GL.glPixelStorei(GL.GL_PACK_ALIGNMENT, 4)
        GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, self.id)
        GL.glReadBuffer(_COLOURS[0])
        pixels = GL.glReadPixels(0, 0, self.width, self.height, self._read, GL.GL_FLOAT)
        shape = (self.height, self.width) if self.channels == 1 else (self.height, self.width, self.channels)
        return np.array(pixels, dtype=np.float32).reshape(shape)


class LevelsFramebuffer:
    """Three single-sampled RGBA8UI colour renderbuffers of ``width`` x ``height`` pixels, without depth: the
    lens's resampling pass (``render.resample``) writes each pixel's 8-bit levels into them as integers (no
    normalisation, no rounding of its own), drawn upright: the first row in memory is the fragments' first
    row (``gl_FragCoord.y = 0.5``).

    Raises:
        RuntimeError: the driver reports it incomplete.
    """

    _FORMATS = {1: GL.GL_RED_INTEGER, 3: GL.GL_RGB_INTEGER, 4: GL.GL_RGBA_INTEGER}
    """channels read -> read-back format."""

    def __init__(self, width: int, height: int):
        self.width, self.height = width, height
        self.id, _ = _new_framebuffer(width, height, 1, len(_COLOURS), GL.GL_RGBA8UI, depth=False)

    def begin_drawing(self, outputs: int) -> None:
        """Make it the draw framebuffer, drawing the fragment shader's first ``outputs`` outputs over all of it."""
        GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, self.id)
        GL.glDrawBuffers(outputs, _COLOURS[:outputs])
        GL.glViewport(0, 0, self.width, self.height)

    def read(self, output: int, channels: int) -> np.ndarray:
        """The first ``channels`` (1, 3 or 4) levels of output ``output``: ``(height, width)`` (one) or ``(height,
        width, channels)`` uint8, the first row drawn first (read-only)."""
        GL.glPixelStorei(GL.GL_PACK_ALIGNMENT, 1)
        GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, self.id)
        GL.glReadBuffer(_COLOURS[output])
        pixels = GL.glReadPixels(0, 0, self.width, self.height, self._FORMATS[channels], GL.GL_UNSIGNED_BYTE)
        shape = (self.height, self.width) if channels == 1 else (self.height, self.width, channels)
        return np.frombuffer(pixels, dtype=np.uint8).reshape(shape)
