"""The lens's resampling pass: each view's canvas window (``render.canvas``) bent into its distorted
output view in GL, so that only output-sized pixels come back.

A view seen through a lens (``sidar_torch.sample.lens_views``) is drawn over a canvas window of its
pinhole pixel grid; every pixel of the distorted view then takes its levels from where its ray meets
the pinhole view, bilinearly. :class:`Resampler` does that right after the view's passes: it uploads
the window's per-view planes into layers of an R32UI array texture, four 8-bit levels a texel (layer 0
the colour pass's RGB and a state byte: 0 painting seen, 1 masked, 2 background; further layers the
optional outputs' channels), and draws one triangle over a :class:`~.framebuffer.LevelsFramebuffer` of
the output's size per layer with ``shaders/resample.frag``. Each fragment computes its source in
float32 (the lens model's define, :data:`MODEL_DEFINES`), clamps it to the window (``grid_sample``'s
border padding) and blends the four window pixels around it with float weights (one ``textureGather``),
levels rounded half to even, as ``torch.nn.functional.grid_sample`` (bilinear, ``align_corners=True``)
and ``round`` did on the CPU before: against that, at the exact maps, at most 1 level on about 3e-5 of
the pixels, masks alike (``tests/render/test_lens.py``). The mask and the background are blended as
fractions and cut at 1/2 (outputs 1 and 2 of layer 0's draw). Only the output's pixels are read back.

Sources. ``division`` in closed form; ``brown_conrady`` by Newton's method from ``x_d / (1 + k1 r^2 + k2
r^4 + k3 r^6)`` (``r = |x_d|``), as many steps as the view needs (:attr:`LensResampling.steps`: 2 for most
lenses of the default ranges, 4 or 8 for strong ones), each count a program of its own (a loop with a
uniform count cost about 0.45 ms more per 384 x 512 view on llvmpipe than the same steps written out).
The float32 sources are within 2.2e-4 px of the exact maps for the default ranges at 384 x 512 and 768 x
1024 (``tests/render/test_canvas.py`` draws them: ``SceneRenderer.lens_sources``).
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass
from typing import Iterator

import numpy as np
from OpenGL import GL

from ..choices.lenses import LENS_MODELS, corner_coefficients, lens_folds
from ..scene import SceneSequence
from .framebuffer import FloatFramebuffer, LevelsFramebuffer
from .programs import Program, ProgramCache

__all__ = ["ITERATION_SLACK", "MODEL_DEFINES", "STEP_CHOICES", "LensResampling", "Resampler", "border_pixels"]

MODEL_DEFINES = {"brown_conrady": "LENS_BROWN_CONRADY", "division": "LENS_DIVISION"}
"""The resampling shader's define of each lens model (``choices.lenses.LENS_MODELS``' rows)."""

STEP_CHOICES = (2, 4, 8, 16)
"""Newton steps an iterative model's program may take (a program each; the default ranges need 2)."""

ITERATION_SLACK = 1e-5
"""Pixels by which one more Newton step may still move the source of any of a view's border pixels after its
steps: about the error Newton's method leaves there (its steps shrink quadratically), far under the float32
rounding of the shader's arithmetic (about 1e-4 px)."""

_SHADERS = ("resample.vert", "resample.frag")


def border_pixels(image_size: tuple[int, int]) -> np.ndarray:
    """``(N, 2)`` float64 Kornia pixels ``(u, v)`` of every pixel on the border of an image of ``image_size``
    (first and last row and column, corners once): where a lens view's sources reach farthest (a lens that
    does not fold maps the view's border onto the border of what it sees)."""
    h, w = image_size
    rows, cols = np.arange(w, dtype=np.float64), np.arange(1, h - 1, dtype=np.float64)
    edges = [np.stack([rows, np.zeros(w)], 1), np.stack([rows, np.full(w, h - 1.0)], 1),
             np.stack([np.zeros(len(cols)), cols], 1), np.stack([np.full(len(cols), w - 1.0), cols], 1)]
    return np.unique(np.concatenate(edges), axis=0)


def _border_sources(model: str, lenses: np.ndarray, K: np.ndarray, image_size: tuple[int, int]
                    ) -> tuple[np.ndarray, np.ndarray]:
    """The pass's sources of every view's border pixels, in float64, and each view's Newton steps.

    A closed-form model's sources are its answers (0 steps). An iterative one starts where the shader does,
    at ``x_d / a(|x_d|^2)`` (``a`` the radial factor), and takes Newton steps (``choices.lenses``' own, all views
    at once): a view's count is the fewest of :data:`STEP_CHOICES` after which the next step moves none of its
    border sources by :data:`ITERATION_SLACK` pixels or more (the sources returned are the iterate after the
    last step taken, at least one more).

    Returns:
        ``(V, N, 2)`` float64 pixels of :func:`border_pixels` 's sources, ``(V,)`` int64 steps.

    Raises:
        ValueError: a view whose steps still move its sources after the most of :data:`STEP_CHOICES` (a lens
            that folds the view).
    """
    row = LENS_MODELS[model]
    pixels = border_pixels(image_size)
    fx, skew, cx, fy, cy = (K[:, i, j, None] for i, j in ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2)))  # (V, 1) each
    y = (pixels[:, 1] - cy) / fy  # (V, N)
    x = (pixels[:, 0] - cx - skew * y) / fx
    coefficients = np.asarray(lenses, np.float64).T[..., None]  # (5, V, 1): each coefficient per view
    steps = np.zeros(len(K), np.int64)
    if not row.iterative:
        u, v = row.undistort((x, y), coefficients, None, None)
    else:
        k1, k2, _, _, k3 = coefficients
        d2 = x * x + y * y
        a = 1 + d2 * (k1 + d2 * (k2 + d2 * k3))
        u, v = x / a, y / a
        for count in range(STEP_CHOICES[-1] + 1):
            next_u, next_v = row.undistort((x, y), coefficients, (u, v), 1)
            moves = np.maximum(np.abs(fx * (next_u - u) + skew * (next_v - v)), np.abs(fy * (next_v - v))).max(axis=1)
            u, v = next_u, next_v
            if count in STEP_CHOICES:  # the error after ``count`` steps is about what the next one moved
                steps[(steps == 0) & (moves < ITERATION_SLACK)] = count
                if steps.all():
                    break
        if not steps.all():  # only lenses that fold do not settle (choices.lenses.lens_folds' tests measure it)
            raise ValueError(f"lenses: {model} {lenses[steps == 0].tolist()} still move their sources after "
                             f"{STEP_CHOICES[-1]} Newton steps from the shader's start (lenses that fold their view: "
                             f"choices.lenses.lens_folds)")
    return np.stack([fx * u + skew * v + cx, fy * v + cy], -1), steps


@dataclass(frozen=True)
class LensResampling:
    """How a render bends each view's canvas window into its distorted view (``SceneRenderer.render``'s ``lens``).

    Attributes:
        model: a lens model (a row of ``choices.lenses.LENS_MODELS``).
        lenses: ``(V, 5)`` float64 coefficients, normalised camera coordinates.
        K: ``(V, 3, 3)`` float64 pinhole intrinsics of the views (output pixels).
        steps: ``(V,)`` int64 Newton steps of each view's program (0: a closed form).
        border: ``(V, N, 2)`` float64 Kornia pixels of the undistorted view: where the pass reads each view's
            border pixels (:func:`border_pixels`), as it computes them but in float64 (its float32 sources are
            within about 2e-4 px of these): what the view's canvas window must hold.
    """

    model: str
    lenses: np.ndarray
    K: np.ndarray
    steps: np.ndarray
    border: np.ndarray

    @classmethod
    def of(cls, sequence: SceneSequence) -> "LensResampling":
        """The resampling of ``sequence``'s lenses (:func:`_border_sources`).

        Raises:
            ValueError: ``sequence`` has no lens (``lens_model`` ``"none"``); a lens that folds its view
                (``choices.lenses.lens_folds``, the test that the config's ranges pass: such a lens comes only
                from a sequence made or changed by hand).
        """
        if sequence.lens_model not in MODEL_DEFINES:
            raise ValueError(f"sequence.lens_model: expected one of {sorted(MODEL_DEFINES)}, got {sequence.lens_model!r}")
        K = sequence.cameras()[0]
        lenses = np.asarray(sequence.lenses, np.float64)
        image_size = tuple(sequence.image_size)
        border, steps = _border_sources(sequence.lens_model, lenses, K, image_size)
        corners = np.stack([corner_coefficients(sequence.lens_model, lens, k, image_size) for lens, k in zip(lenses, K)])
        folding = lens_folds(sequence.lens_model, corners)
        if folding.any():
            raise ValueError(f"lenses: {sequence.lens_model} {lenses[folding].tolist()} (at the image's corner "
                             f"{corners[folding].tolist()}) fold their view over the image (choices.lenses.lens_folds, "
                             f"which the config's lens ranges pass)")
        return cls(sequence.lens_model, lenses, K, steps, border)


class Resampler:
    """The resampling pass of one GL context (current whenever a method is called), drawing output views of
    ``image_size`` ``(H, W)``: its programs come from ``programs`` (the renderer's cache)."""

    def __init__(self, programs: ProgramCache, image_size: tuple[int, int]):
        self.image_size = tuple(image_size)
        self._programs = programs
        self._target = LevelsFramebuffer(image_size[1], image_size[0])
        self._sources_target: FloatFramebuffer | None = None
        self._vertex_array = int(GL.glGenVertexArrays(1))  # the triangle has no attributes; core GL wants one bound
        self._texture: int | None = None
        self._capacity = (0, 0, 0)  # (width, height, layers) of the array texture's storage

    def resample(self, lens: LensResampling, index: int, origin: np.ndarray, colour: np.ndarray, mask: np.ndarray,
                 outputs: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, np.ndarray]]:
        """View ``index``'s canvas window, bent through its lens into the output's ``image_size``.

        Args:
            lens: the sequence's resampling.
            index: the view.
            origin: ``(2,)`` int, the view pixel ``(x, y)`` at the window's pixel ``(0, 0)`` (``Canvas.origins``).
            colour: ``(h, w, 4)`` uint8, the colour pass's RGB and alpha (0: nothing drawn, background) over the
                window; its alpha is overwritten (with the state byte).
            mask: ``(h, w)`` bool, True where the painting is not visible.
            outputs: the view's optional outputs over the window, ``(h, w)`` or ``(h, w, C)`` uint8 levels.

        Returns:
            ``(H, W, 3)`` uint8 RGB, ``(H, W)`` bool mask, ``(H, W)`` bool background (each blended as a fraction
            and cut at 1/2) and ``outputs`` at ``(H, W)`` / ``(H, W, C)`` uint8.

        Raises:
            ValueError: an output not of uint8 levels (values a lens may not blend: ``OptionalOutput.lens_resample``).
        """
        for name, array in outputs.items():
            if array.dtype != np.uint8:
                raise ValueError(f"outputs[{name!r}]: expected uint8 levels through a lens, got {array.dtype}")
        h, w = mask.shape
        np.add(mask, colour[..., 3] == 0, out=colour[..., 3], dtype=np.uint8)  # 0 seen, 1 masked, 2 background
        names = sorted(outputs)
        blocks = [outputs[name].reshape(h, w, -1) for name in names]
        extra = np.zeros((-(-sum(block.shape[2] for block in blocks) // 4), h, w, 4), np.uint8)  # 4 levels a texel
        channel = 0
        for block in blocks:
            for c in range(block.shape[2]):
                extra[(channel + c) // 4, ..., (channel + c) % 4] = block[..., c]
            channel += block.shape[2]
        self._upload([colour, *extra])
        program = self._program(lens, index, sources=False)
        self._draw(program, lens, index, origin, (h, w), 0, outputs=3)
        rgb, masked, background = (self._target.read(0, 3), self._target.read(1, 1).view(bool),
                                   self._target.read(2, 1).view(bool))
        levels = []
        for layer in range(1, 1 + len(extra)):
            self._draw(program, lens, index, origin, (h, w), layer, outputs=1)
            levels.append(self._target.read(0, 4))
        resampled, channel = {}, 0
        if levels:
            flat = np.concatenate(levels, axis=-1)
            for name, block in zip(names, blocks):
                n = block.shape[2]
                resampled[name] = np.ascontiguousarray(flat[..., channel:channel + n]).reshape(
                    *self.image_size, *outputs[name].shape[2:])
                channel += n
        return rgb, masked, background, resampled

    def sources(self, lens: LensResampling, index: int) -> np.ndarray:
        """Where the pass reads each pixel of view ``index``: ``(H, W, 2)`` float32 Kornia pixels ``(u, v)`` of
        the undistorted view, drawn by the same shader (its ``SOURCES`` variant), before the window's clamp."""
        if self._sources_target is None:
            self._sources_target = FloatFramebuffer(self.image_size[1], self.image_size[0], 3)
        target = self._sources_target
        program = self._program(lens, index, sources=True)
        with _resampling_state():
            target.begin_drawing()
            GL.glViewport(0, 0, self.image_size[1], self.image_size[0])
            program.use()
            self._set_lens(program, lens, index)
            GL.glBindVertexArray(self._vertex_array)
            GL.glDrawArrays(GL.GL_TRIANGLES, 0, 3)
            GL.glBindVertexArray(0)
            GL.glUseProgram(0)
        return np.ascontiguousarray(target.end_drawing()[..., :2])

    def _program(self, lens: LensResampling, index: int, sources: bool) -> Program:
        defines = {MODEL_DEFINES[lens.model]: 1}
        if lens.steps[index]:
            defines["NEWTON_STEPS"] = int(lens.steps[index])
        if sources:
            defines["SOURCES"] = 1
        program = self._programs.get(_SHADERS, defines)
        program.link()
        return program

    @staticmethod
    def _set_lens(program: Program, lens: LensResampling, index: int) -> None:
        K, coefficients = lens.K[index], lens.lenses[index]
        program.set_uniform("intrinsics", np.array([K[0, 0], K[0, 1], K[0, 2], K[1, 1]]))
        program.set_uniform("c_y", float(K[1, 2]))
        program.set_uniform("lens", np.asarray(coefficients[:4], np.float64))
        program.set_uniform("k3", float(coefficients[4]))

    def _upload(self, layers: list[np.ndarray]) -> None:
        """Put ``layers`` (each ``(h, w, 4)`` uint8, contiguous) into the array texture's first layers, rows
        and columns (its storage grows to hold them)."""
        h, w = layers[0].shape[:2]
        if w > self._capacity[0] or h > self._capacity[1] or len(layers) > self._capacity[2]:
            if self._texture is not None:
                GL.glDeleteTextures([self._texture])
            self._capacity = tuple(max(a, b) for a, b in zip(self._capacity, (w, h, len(layers))))
            self._texture = int(GL.glGenTextures(1))
            GL.glBindTexture(GL.GL_TEXTURE_2D_ARRAY, self._texture)
            GL.glTexStorage3D(GL.GL_TEXTURE_2D_ARRAY, 1, GL.GL_R32UI, *self._capacity)
            for name, value in ((GL.GL_TEXTURE_MIN_FILTER, GL.GL_NEAREST), (GL.GL_TEXTURE_MAG_FILTER, GL.GL_NEAREST),
                                (GL.GL_TEXTURE_WRAP_S, GL.GL_CLAMP_TO_EDGE), (GL.GL_TEXTURE_WRAP_T, GL.GL_CLAMP_TO_EDGE)):
                GL.glTexParameteri(GL.GL_TEXTURE_2D_ARRAY, name, value)
        GL.glBindTexture(GL.GL_TEXTURE_2D_ARRAY, self._texture)
        for layer, array in enumerate(layers):
            texels = np.ascontiguousarray(array).view(np.uint32)  # a pixel's 4 levels, byte 0 the lowest (little-endian)
            GL.glTexSubImage3D(GL.GL_TEXTURE_2D_ARRAY, 0, 0, 0, layer, w, h, 1, GL.GL_RED_INTEGER,
                               GL.GL_UNSIGNED_INT, texels)
        GL.glBindTexture(GL.GL_TEXTURE_2D_ARRAY, 0)

    def _draw(self, program: Program, lens: LensResampling, index: int, origin: np.ndarray, window: tuple[int, int],
              layer: int, outputs: int) -> None:
        """Draw layer ``layer`` of view ``index`` into the first ``outputs`` outputs of the levels target."""
        h, w = window
        with _resampling_state():
            self._target.begin_drawing(outputs)
            program.use()
            self._set_lens(program, lens, index)
            program.set_uniform("canvas", 0)
            program.set_uniform("layer", layer)
            program.set_uniform("texture_size", np.array(self._capacity[:2], np.float64))
            program.set_uniform("window", np.array([w, h], np.float64))
            program.set_uniform("origin", np.asarray(origin, np.float64))
            GL.glActiveTexture(GL.GL_TEXTURE0)
            GL.glBindTexture(GL.GL_TEXTURE_2D_ARRAY, self._texture)
            GL.glBindVertexArray(self._vertex_array)
            GL.glDrawArrays(GL.GL_TRIANGLES, 0, 3)
            GL.glBindVertexArray(0)
            GL.glBindTexture(GL.GL_TEXTURE_2D_ARRAY, 0)
            GL.glUseProgram(0)


_CAPABILITIES = (GL.GL_DEPTH_TEST, GL.GL_STENCIL_TEST, GL.GL_SCISSOR_TEST, GL.GL_BLEND, GL.GL_CULL_FACE)
"""What the pass turns off (every fragment is drawn once, untested and unblended)."""


@contextlib.contextmanager
def _resampling_state() -> Iterator[None]:
    """Inside: :data:`_CAPABILITIES` off; after: those that were on, on again (the passes set the rest themselves)."""
    enabled = [capability for capability in _CAPABILITIES if GL.glIsEnabled(capability)]
    for capability in enabled:
        GL.glDisable(capability)
    try:
        yield
    finally:
        for capability in enabled:
            GL.glEnable(capability)
