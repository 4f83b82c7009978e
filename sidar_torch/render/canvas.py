"""Where a render draws each view in its camera's pixel grid: a :class:`Canvas`, a render size apart
from the output size.

By default a view is drawn over its own ``image_size`` pixels. A canvas draws every view of a render
over a window of ``size`` pixels of its camera's pixel grid (the camera's full, unbounded grid:
Kornia pixels, integer centres) whose top-left pixel is the view's pixel ``origins[i]``: the same
camera with its principal point moved by ``-origins[i]`` (``K[0, 2] -= x``, ``K[1, 2] -= y``; the same
focal length, so canvas pixel ``(u, v)`` is view pixel ``(u + x, v + y)``) drawn into a framebuffer
of ``size``. A window larger than the view is an overscan (the wider undistorted canvas a lens
resamples, ``sidar_torch.sample.lens_views``), a smaller one a crop. Each view may draw a window of its
own, ``sizes[i]``, at most ``size``: the arrays of a render are ``size`` (so they stack), each view's
pixels in their first rows and columns and nothing beyond (zeros; masks and background true). The
painting (its plane and texture) and the label keep ``image_size`` and view 0's own camera.

Origins should be even (:data:`QUAD`): the rasteriser shades 2 x 2 pixel quads, and the texture's mip
level comes from differences within a quad, so a window shifted by an odd pixel regroups the quads and
reads the painting at other levels (up to 9 levels on a third of an oblique view's pixels at 96 x 128);
with even origins a canvas's pixels are the view's up to the projection's rounding (at most 3 levels,
on under 0.1 % of the painting's pixels; ``tests/render/test_canvas.py``).
"""

from __future__ import annotations

import dataclasses
import operator
from dataclasses import dataclass

import numpy as np

from ..scene import Camera, SceneSequence

__all__ = ["QUAD", "Canvas"]

QUAD = 2
"""Side of the rasteriser's pixel quads: a canvas origin that is a multiple of it keeps the view's quads."""


@dataclass(frozen=True, eq=False)
class Canvas:
    """The window of each view's pixel grid a render draws.

    Attributes:
        size: ``(H, W)`` pixels of the arrays handed out: the largest window.
        origins: ``(V, 2)`` int64, the ``(x, y)`` view pixel (Kornia) at each view's canvas pixel
            ``(0, 0)``; all zeros with ``size`` the image's: the views themselves.
        sizes: ``(V, 2)`` int64, the ``(H, W)`` window each view draws, each at most ``size``; None
            (the default): ``size`` for every view.

    Raises:
        ValueError: ``size`` not two integers >= 1; ``origins`` not ``(V, 2)`` integers; ``sizes`` not
            ``(V, 2)`` integers from 1 to ``size``.
    """

    size: tuple[int, int]
    origins: np.ndarray
    sizes: np.ndarray | None = None

    def __post_init__(self) -> None:
        try:
            size = tuple(operator.index(n) for n in self.size)
        except TypeError:
            size = ()
        if len(size) != 2 or min(size) < 1:
            raise ValueError(f"canvas size: expected (H, W), two integers >= 1, got {self.size!r}")
        origins = np.asarray(self.origins)
        if origins.ndim != 2 or origins.shape[1] != 2 or not (np.issubdtype(origins.dtype, np.integer)
                                                              or len(origins) == 0):
            raise ValueError(f"canvas origins: expected (V, 2) integer (x, y) pixels, got shape {origins.shape} "
                             f"{origins.dtype}")
        object.__setattr__(self, "size", size)
        object.__setattr__(self, "origins", origins.astype(np.int64))
        sizes = np.tile(size, (len(origins), 1)) if self.sizes is None else np.asarray(self.sizes)
        if (sizes.shape != origins.shape or not (np.issubdtype(sizes.dtype, np.integer) or len(sizes) == 0)
                or (len(sizes) and (sizes.min() < 1 or (sizes > size).any()))):
            raise ValueError(f"canvas sizes: expected (V, 2) integer (H, W) windows from 1 to size {size}, one per "
                             f"origin, got {sizes.tolist()}")
        object.__setattr__(self, "sizes", sizes.astype(np.int64))

    def window(self, index: int) -> tuple[int, int]:
        """The ``(H, W)`` window view ``index`` draws."""
        return int(self.sizes[index, 0]), int(self.sizes[index, 1])

    @classmethod
    def covering(cls, boxes: np.ndarray) -> "Canvas":
        """The canvas with even origins (:data:`QUAD`) whose windows are every view's box of pixels:
        ``boxes (V, 4)`` int ``(x0, y0, x1, y1)``, inclusive view pixels; each view's origin is its box's
        top-left rounded down to a multiple of :data:`QUAD`, its window the box from there."""
        boxes = np.asarray(boxes, np.int64).reshape(-1, 4)
        if len(boxes) == 0 or (boxes[:, 2:] < boxes[:, :2]).any():
            raise ValueError(f"boxes: expected (V >= 1, 4) (x0, y0, x1, y1) with x1 >= x0 and y1 >= y0, got {boxes.tolist()}")
        origins = boxes[:, :2] // QUAD * QUAD
        spans = boxes[:, 2:] - origins + 1
        return cls((int(spans[:, 1].max()), int(spans[:, 0].max())), origins, spans[:, ::-1])

    def camera(self, camera: Camera, index: int) -> Camera:
        """``camera`` (view ``index``'s) drawing this canvas: its principal point moved by ``-origins[index]``."""
        K = camera.K.copy()
        K[:2, 2] -= self.origins[index]
        return Camera(K, camera.R, camera.t)

    def views(self, sequence: SceneSequence) -> SceneSequence:
        """``sequence`` with every view's camera drawing this canvas (:meth:`camera`); its ``image_size``
        (the painting's, the label's) unchanged.

        Raises:
            ValueError: not one origin per view.
        """
        if len(self.origins) != len(sequence.views):
            raise ValueError(f"canvas origins: expected one per view ({len(sequence.views)}), got {len(self.origins)}")
        views = tuple(dataclasses.replace(view, camera=self.camera(view.camera, i)) for i, view in enumerate(sequence.views))
        return dataclasses.replace(sequence, views=views)
