"""Shadow footprints: where on a view's painting each shadowed emitter's lookups can change a pixel.

Only a small part of a view's painting lies where a caster can shadow it, yet the lit shader runs
every shadowed emitter's lookups at every painting fragment (with the ``misaligned`` preset about
two thirds of them cannot find a caster). So the painting's colour draw is split into screen
rectangles (:class:`PaintingPart`), each drawn under a scissor with only the lookups it needs; the
occluders keep all of them.

Why a part's pixels are the same as with every lookup. The shader adds the spot lights' groups in
their order in three loops (``programs`` quirks 6 and 13): groups in ``[0, begin)`` without a
lookup, ``[begin, end)`` with one, ``[end, n)`` without. A group adds its shade times its emitters'
summed visibility with a lookup, times its number of emitters without. A lookup that reads no
caster's texel returns "lit": a shadow factor of exactly ``1 - 0.25 * 4 = 0`` and a transmittance
of exactly 1, so the visibility ``(1 - 0) * 1`` is exactly 1, the sum of a group's is exactly its
number of emitters, and the sum is the same float sum in the same order whichever loop a light is
in. A part's range ``[begin, end)`` holds every shadowed emitter (the first ones of
``ViewPlan.order``) whose lookups may read a caster at one of its pixels; the emitters it leaves out
would all return "lit" there. A part with an empty range is drawn by the program without lookups,
which adds the same groups in the same order, written out (up to 4) or in one loop.

Where a lookup may read a caster: what ``plan`` tests for a drawn occluder
(:func:`~.visibility.shadow_may_fall_on_ball`), with every caster's ball, the emitter's lookup
margin (:func:`~.plan.shadow_margin`) and, as the target, a ball holding the part of the plane a
tile of ``RenderSettings.footprint_tile`` pixels square sees (the tile's corners, at the outer pixel borders,
cast onto ``z = 0``): every fragment shaded in the tile, at its pixel centre or at a sample point
inside the pixel (``antialias``), lies in that ball. A tile reaching the camera's horizon needs
every lookup. ``tests/render/test_skips.py`` renders with and without the split and compares bit for bit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..scene import ViewScene, occluder_radius
from .visibility import shadow_may_fall_on_ball

__all__ = ["PaintingPart", "lookup_ranges", "painting_parts"]


@dataclass(frozen=True)
class PaintingPart:
    """A screen rectangle of a view whose painting fragments look up only the shadowed emitters
    ``begin .. end - 1`` (indices into ``ViewPlan.order``; ``begin == end``: none).

    Attributes:
        x, y: first column and row, pixels (row 0 is the image's top row, which is also the
            framebuffer's first row: forward passes draw upside down, see ``framebuffer``).
        width, height: size, pixels.
        begin, end: the lookup range.
    """

    x: int
    y: int
    width: int
    height: int
    begin: int
    end: int


def _tile_balls(view: ViewScene, image_size: tuple[int, int], tile: int) -> tuple[np.ndarray, np.ndarray]:
    """Balls holding what each ``tile`` x ``tile`` pixel tile sees of the plane ``z = 0``: centres
    ``(ny, nx, 3)`` and radii ``(ny, nx)`` (world, painting units; ``inf`` for a tile whose corners are
    not all in front of the camera)."""
    h, w = image_size
    cam = view.camera
    us = np.minimum(np.arange(0, w + tile, tile), w) - 0.5  # outer pixel borders (Kornia pixels)
    vs = np.minimum(np.arange(0, h + tile, tile), h) - 0.5
    to_plane = np.linalg.inv(cam.K @ np.column_stack([cam.R[:, 0], cam.R[:, 1], cam.t]))
    u, v = np.meshgrid(us, vs)
    p = np.einsum("ij,jyx->iyx", to_plane, np.stack([u, v, np.ones_like(u)]))  # homogeneous plane points
    front = p[2] > 0
    xy = p[:2] / np.where(front, p[2], 1.0)
    corners = np.stack([xy[:, :-1, :-1], xy[:, 1:, :-1], xy[:, :-1, 1:], xy[:, 1:, 1:]], axis=-1)  # (2, ny, nx, 4)
    seen = front[:-1, :-1] & front[1:, :-1] & front[:-1, 1:] & front[1:, 1:]
    centres = corners.mean(axis=-1)
    radii = np.where(seen, np.linalg.norm(corners - centres[..., None], axis=0).max(axis=-1), np.inf)
    return np.stack([centres[0], centres[1], np.zeros_like(radii)], axis=-1), radii


def lookup_ranges(view: ViewScene, emitters: list[tuple[int, int]], casters: list[int], margins: np.ndarray,
                  image_size: tuple[int, int], tile: int) -> tuple[np.ndarray, np.ndarray]:
    """Per tile, the range of shadowed emitters whose lookups may read a caster there.

    Args:
        view: the scene (camera, lights, occluders).
        emitters: the shadowed emitters as ``(light, emitter)`` indices of ``view.lights``, in lookup order.
        casters: indices of ``view.occluders`` in the shadow and transmittance maps.
        margins: ``(E,)`` each emitter's lookup margin, radians (:func:`~.plan.shadow_margin`).
        image_size: ``(H, W)``, pixels.
        tile: side of the square tiles, pixels (``RenderSettings.footprint_tile``).

    Returns:
        ``begin, end``: ``(ny, nx)`` int arrays over the tiles (row-major from the top-left tile);
        ``begin == end`` where no lookup is needed.
    """
    centres, radii = _tile_balls(view, image_size, tile)
    positions = np.array([view.lights[a].emitters[b] for a, b in emitters], np.float64).reshape(-1, 3)
    balls = np.array([[*view.occluders[i].position, occluder_radius(view.occluders[i])] for i in casters],
                     np.float64).reshape(-1, 4)
    with np.errstate(invalid="ignore"):  # tiles of infinite radius: inside, results unused
        may = shadow_may_fall_on_ball(positions, balls[:, :3], balls[:, 3], centres.reshape(-1, 3), radii.ravel(),
                                      margins).any(axis=1)  # (E, tiles)
    may |= ~np.isfinite(radii.ravel())
    k = np.arange(len(emitters))[:, None]
    end = np.where(may, k + 1, 0).max(axis=0, initial=0)
    begin = np.minimum(np.where(may, k, len(emitters)).min(axis=0, initial=len(emitters)), end)
    return begin.reshape(radii.shape), end.reshape(radii.shape)


def painting_parts(begin: np.ndarray, end: np.ndarray, image_size: tuple[int, int], tile: int) -> list[PaintingPart]:
    """Screen rectangles tiling the image, each with the lookup range its tiles need.

    Tiles of a row with the same range are merged into runs; a run the same as one of the row above
    extends it downwards.

    Args:
        begin, end: ``(ny, nx)`` per-tile lookup ranges (:func:`lookup_ranges`).
        image_size: ``(H, W)``, pixels.
        tile: side of the tiles, pixels, as given to :func:`lookup_ranges`.

    Returns:
        The parts, covering every pixel once.
    """
    h, w = image_size
    same = (begin == end)
    begin, end = np.where(same, 0, begin), np.where(same, 0, end)  # one key for "no lookup"
    changes = (begin[:, 1:] != begin[:, :-1]) | (end[:, 1:] != end[:, :-1])  # a run ends left of the change
    begins, ends = begin.tolist(), end.tolist()
    parts: list[PaintingPart] = []
    above: dict[tuple[int, int, int, int], PaintingPart] = {}
    for row in range(begin.shape[0]):
        y, height = row * tile, min(tile, h - row * tile)
        cuts = (np.flatnonzero(changes[row]) + 1).tolist()
        runs = {}
        for first, stop in zip([0, *cuts], [*cuts, begin.shape[1]]):
            key = (first, stop, begins[row][first], ends[row][first])
            top = above[key].y if key in above else y
            x = first * tile
            runs[key] = PaintingPart(x, top, min(stop * tile, w) - x, y + height - top, key[2], key[3])
        parts += [part for key, part in above.items() if key not in runs]
        above = runs
    return parts + list(above.values())
