"""What a camera or a light can see: the conservative culling geometry only the renderer uses.

Float64 numpy, no GL, in ``sidar_torch.geometry``'s frames and pixel conventions (world: the
painting in z = 0 facing +z; cameras: OpenCV frame, ``K (R X + t)``; Kornia pixels). Occluders
are bounded by balls ``|X - centre| <= radius`` about an occluder's ``position``: of radius
``scene.occluder_radius`` (its shape's tightest bound) where the ball only decides what is skipped
(culling, casters, footprints), and ``|scale|`` where it sets what is drawn (shadow frusta, soft
reach, mesh levels), which a tighter ball would change.

* culling: :func:`ball_may_be_seen` (:func:`balls_may_be_seen`), :func:`shadow_may_reach`,
  :func:`shadow_may_fall_on_ball` (``render.plan`` decides with them what each view draws);
* mesh detail: :func:`ball_pixel_radius`, :func:`ball_shadow_pixel_radii` (how large an occluder
  and its shadow show, in pixels);
* shadow maps: :func:`light_frustum` (:func:`light_frusta`), :func:`cube_corners`; which texels a draw into a map may
  write: :func:`map_texel_box` (:func:`map_texel_boxes`) of :func:`bounds_corners`;
* masks without a draw: :func:`painting_mask`.

Every test is conservative where it culls: ``False`` ("cannot be seen") only when certain.
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from ..geometry import look_at, plane_size, project, view_edges

__all__ = [
    "ball_may_be_seen",
    "balls_may_be_seen",
    "ball_pixel_radius",
    "ball_shadow_corners",
    "ball_shadow_pixel_radii",
    "bounds_corners",
    "cube_corners",
    "light_frustum",
    "light_frusta",
    "map_texel_box",
    "map_texel_boxes",
    "painting_mask",
    "shadow_may_fall_on_ball",
    "shadow_may_reach",
]


def ball_may_be_seen(K: np.ndarray, R: np.ndarray, t: np.ndarray, image_size: tuple[int, int],
                     centre: np.ndarray, radius: float) -> bool:
    """Whether a ball ``|X - centre| <= radius`` (world) may show in a camera's image.

    Conservative: ``False`` only when the ball lies wholly outside one of the view's bounding
    planes (the four image edges and the camera's front).
    """
    return balls_may_be_seen(K, R, t, image_size, [centre], [radius])[0]


def balls_may_be_seen(K: np.ndarray, R: np.ndarray, t: np.ndarray, image_size: tuple[int, int],
                      centres: Sequence[np.ndarray], radii: Sequence[float]) -> list[bool]:
    """:func:`ball_may_be_seen` of each ball ``centres[k]`` ``(3,)``, ``radii[k]``: the view's bounding
    planes computed once, each ball's test as it has it alone (the same arithmetic)."""
    edges = view_edges(K, image_size)
    norms = np.linalg.norm(edges, axis=1)
    return [bool((edges @ (R @ centre + t) / norms >= -radius).all()) for centre, radius in zip(centres, radii)]


_CUBE = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=np.float64)
"""The corners ``(8, 3)`` of the cube of half-side 1 around the origin."""


def shadow_may_reach(emitters: np.ndarray, centres: np.ndarray, radii: np.ndarray, region: np.ndarray,
                     margins: np.ndarray | float = 0.0) -> np.ndarray:
    """Whether each ball can shadow any part of a region of the painting's plane, lit from each point.

    Conservative: ``False`` only when the shadow certainly misses. A ball ``|X - c| <= r`` lies in
    the cube of half-side ``r`` around ``c``; seen from an emitter above the cube, its shadow on
    ``z = 0`` lies in the convex hull of the cube's 8 corners projected from the emitter, and so in
    their bounding box, which is tested against the region (separating axes: the box's two and the
    region's edge normals). A ball reaching the emitter's height has an unbounded shadow.

    ``margins`` widen each emitter's shadows by an angle: every plane point whose direction from
    the emitter is within the margin of a ball's is tested too. The ball is grown to radius
    ``r + D margin`` (``D`` its centre's distance from the emitter), whose cone of directions holds
    the widened one (``asin(x + m) >= asin(x) + m``).

    Args:
        emitters: ``(E, 3)`` light positions (world, painting units), ``z > 0``.
        centres, radii: ``(B, 3)`` and ``(B,)`` balls (world, painting units).
        region: ``(N, 2)`` convex polygon on the plane ``z = 0`` (e.g. what a camera sees).
        margins: ``(E,)`` or one angle, radians.

    Returns:
        ``(E, B)`` bool.
    """
    emitters, centres = np.asarray(emitters, np.float64), np.asarray(centres, np.float64).reshape(-1, 3)
    if len(region) < 3:
        return np.zeros((len(emitters), len(centres)), dtype=bool)
    distance = np.linalg.norm(centres[None] - emitters[:, None], axis=2)
    grown = np.asarray(radii, np.float64)[None] + distance * np.reshape(margins, (-1, 1))  # (E, B)
    unbounded = centres[None, :, 2] + grown >= emitters[:, None, 2]
    corners = centres[None, :, None] + grown[..., None, None] * _CUBE  # (E, B, 8, 3)
    light = emitters[:, None, None]
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):  # unbounded shadows: results unused
        scale = light[..., 2] / (light[..., 2] - corners[..., 2])
        shadow = light[..., :2] + scale[..., None] * (corners[..., :2] - light[..., :2])
        return unbounded | _boxes_meet_polygon(shadow.min(axis=2), shadow.max(axis=2), region)


def _boxes_meet_polygon(lo: np.ndarray, hi: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Whether axis-aligned boxes ``[lo, hi]`` (``(..., 2)`` each) meet a convex polygon ``(N, 2)``
    (touching counts), by separating axes: the two axes, then each edge's outward normal. A
    polygon too thin for its orientation to be sure meets every box."""
    apart = (hi < polygon.min(axis=0)).any(axis=-1) | (lo > polygon.max(axis=0)).any(axis=-1)
    edges = np.roll(polygon, -1, axis=0) - polygon
    twice_area = float(edges[:, 0] @ (np.roll(polygon, -1, axis=0)[:, 1] + polygon[:, 1]))  # > 0: clockwise
    if abs(twice_area) <= 1e-9 * float(np.ptp(polygon, axis=0).max()) ** 2:
        return np.ones(lo.shape[:-1], dtype=bool)
    normals = np.stack([edges[:, 1], -edges[:, 0]], axis=1) * -np.sign(twice_area)
    support = np.einsum("na,na->n", normals, polygon)  # the polygon lies where normal . p <= support
    nearest = np.where(normals > 0, lo[..., None, :], hi[..., None, :])  # (..., N, 2): box corner least along each normal
    apart |= (np.einsum("...na,na->...n", nearest, normals) > support).any(axis=-1)
    return ~apart


def shadow_may_fall_on_ball(emitters: np.ndarray, centres: np.ndarray, radii: np.ndarray, targets: np.ndarray,
                            target_radii: np.ndarray, margins: np.ndarray | float = 0.0) -> np.ndarray:
    """Whether each ball can shadow any point of each target ball (or itself), lit from each point.

    Conservative: ``False`` only when no direction from the emitter within its margin (radians)
    of one that meets the ball meets the target, i.e. their cones of directions seen from the
    emitter, widened by the margin, are apart. A ball holding the emitter spans every direction.

    Args:
        emitters: ``(E, 3)`` light positions (world, painting units).
        centres, radii: ``(B, 3)``, ``(B,)`` shadowing balls; targets, target_radii: ``(T, 3)``,
            ``(T,)`` shadowed ones.
        margins: ``(E,)`` or one angle, radians.

    Returns:
        ``(E, B, T)`` bool.
    """
    emitters = np.asarray(emitters, np.float64)
    a = np.asarray(centres, np.float64).reshape(-1, 3)[None] - emitters[:, None]  # (E, B, 3)
    b = np.asarray(targets, np.float64).reshape(-1, 3)[None] - emitters[:, None]  # (E, T, 3)
    da, db = np.linalg.norm(a, axis=2), np.linalg.norm(b, axis=2)
    inside = (da <= radii)[..., None] | (db <= target_radii)[:, None, :]
    with np.errstate(divide="ignore", invalid="ignore"):  # an emitter at a centre: inside, result unused
        cos = np.einsum("eba,eta->ebt", a, b) / (da[..., None] * db[:, None, :])
        between = np.arccos(np.clip(cos, -1.0, 1.0))
        half_a = np.arcsin(np.clip(radii / da, 0.0, 1.0))
        half_b = np.arcsin(np.clip(target_radii / db, 0.0, 1.0))
    return inside | (between <= half_a[..., None] + half_b[:, None, :] + np.reshape(margins, (-1, 1, 1)))


def painting_mask(K: np.ndarray, R: np.ndarray, t: np.ndarray, image_size: tuple[int, int],
                  canvas_size: tuple[int, int] | None = None) -> np.ndarray:
    """``(H, W)`` bool (``canvas_size``'s): True at pixels whose centre does not see the painting (background).

    The camera ray through pixel centre ``(u, v)`` (Kornia pixels, integer centres) meets the
    plane at homogeneous plane point ``p = M^-1 K^-1 (u, v, 1)``, ``M = [r_1, r_2, t]`` (so
    ``(x, y) = p[:2] / p[2]``), in front of the camera when ``p[2] > 0``; it sees the painting when
    moreover ``|x| <= w / 2`` and ``|y| <= h / 2``. Along a row ``p`` is linear in ``u``, so each
    condition holds on a half-line of ``u`` and the seen columns are an interval: the work is
    per row, and exact up to float64 rounding (the same plane geometry as the homographies).
    Nothing is near-clipped: the renderer's near plane lies in front of every painting point in
    view (``render.scene_graph.clip_range``).

    Args:
        K, R: ``(3, 3)``; t: ``(3,)`` float64 camera.
        image_size: ``(H, W)`` in pixels, of the image and of the painting (same aspect).
        canvas_size: ``(H, W)`` the camera draws (``render.canvas``); default ``image_size``.
    """
    h, w = image_size if canvas_size is None else canvas_size
    half_w, half_h = plane_size(image_size)[0] / 2, plane_size(image_size)[1] / 2
    to_plane = np.linalg.inv(np.asarray(K, dtype=np.float64) @ np.column_stack([R[:, 0], R[:, 1], t]))
    # Conditions c . p >= 0: in front, then the painting's four edges.
    conditions = np.array([[0, 0, 1.0], [1, 0, half_w], [-1, 0, half_w], [0, 1, half_h], [0, -1, half_h]])
    step = conditions @ to_plane[:, 0]  # (5,): change per column
    start = (conditions @ to_plane[:, 1:]) @ np.stack([np.arange(h, dtype=np.float64), np.ones(h)])  # (5, H): at u = 0
    with np.errstate(divide="ignore", invalid="ignore"):
        bound = -start / step[:, None]
    lo = np.where(step[:, None] > 0, bound, np.where((step[:, None] == 0) & (start < 0), np.inf, -np.inf)).max(axis=0)
    hi = np.where(step[:, None] < 0, bound, np.where((step[:, None] == 0) & (start < 0), -np.inf, np.inf)).min(axis=0)
    columns = np.arange(w, dtype=np.float64)
    return ~((columns >= lo[:, None]) & (columns <= hi[:, None]))


def cube_corners(centre: np.ndarray, radius: float) -> np.ndarray:
    """``(8, 3)`` corners of the axis-aligned cube of half-side ``radius`` around ``centre``: the
    cube holds the ball ``|X - centre| <= radius``, so their convex hull bounds the ball."""
    return np.asarray(centre, dtype=np.float64) + radius * _CUBE


def bounds_corners(bounds: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """``(8, 3)`` world corners of an object-space axis-aligned box ``bounds`` ``[[x, y, z]_min,
    [x, y, z]_max]`` placed by ``pose`` ``(4, 4)`` (object to world): their convex hull holds the
    posed object."""
    lo, hi = np.asarray(bounds, dtype=np.float64)
    corners = np.where(_CUBE > 0, hi, lo)
    return corners @ pose[:3, :3].T + pose[:3, 3]


def map_texel_box(points: np.ndarray, clip_from_world: np.ndarray, size: int) -> tuple[int, int, int, int]:
    """The texels of a ``size`` x ``size`` map that a draw of geometry inside the convex hull of
    ``points`` may write, through a viewport covering the whole map.

    A texel is written only if its centre lies in a drawn triangle, so only if it lies in the
    bounding box of the points' projections; one more texel on each side covers rounding.
    Conservative: the whole map when a point is not in front of the projection (clip ``w <= 0``).

    Args:
        points: ``(N, 3)`` world points.
        clip_from_world: ``(4, 4)`` projection times view matrix (OpenGL clip space).
        size: the map's side, texels.

    Returns:
        ``(x0, y0, x1, y1)``: texel columns ``x0 .. x1 - 1`` and rows ``y0 .. y1 - 1`` (window
        coordinates, row 0 first in memory), clipped to the map; empty (``x0 == x1``) for no points.
    """
    return map_texel_boxes(points, [clip_from_world], size)[0]


def map_texel_boxes(points: np.ndarray, clip_from_worlds: Sequence[np.ndarray],
                    size: int) -> list[tuple[int, int, int, int]]:
    """:func:`map_texel_box` of the same ``points`` under each of ``clip_from_worlds`` ``(4, 4)`` (a view's
    lights), in one batched product and one set of array operations: each box the one the matrix gets alone
    (the same products per matrix, then elementwise operations and exact minima and maxima)."""
    count = len(clip_from_worlds)
    if not len(points) or not count:
        return [(0, 0, 0, 0)] * count
    homogeneous = np.ones((len(points), 4))
    homogeneous[:, :3] = points
    clip = homogeneous @ np.asarray(clip_from_worlds, np.float64).transpose(0, 2, 1)  # (L, N, 4)
    behind = (clip[..., 3] <= 0).any(axis=1).tolist()
    with np.errstate(divide="ignore", invalid="ignore"):  # a matrix with a point behind it: the whole map
        texels = (clip[..., :2] / clip[..., 3:] * 0.5 + 0.5) * size
    lows = (np.floor(texels.min(axis=1)) - 1).tolist()
    highs = (np.ceil(texels.max(axis=1)) + 1).tolist()
    boxes = []
    for whole, low, high in zip(behind, lows, highs):
        if whole:
            boxes.append((0, 0, size, size))
            continue
        # Clamped in Python floats (np.clip's cost is its dispatch, several times these four numbers').
        (x0, y0), (x1, y1) = ([min(max(v, 0.0), size) for v in bound] for bound in (low, high))
        boxes.append((int(x0), int(y0), int(max(x0, x1)), int(max(y0, y1))))
    return boxes


def ball_shadow_corners(emitters: np.ndarray, centre: np.ndarray, radius: float) -> np.ndarray:
    """The ball's bounding-cube corners projected from point lights onto the plane ``z = 0``:
    ``(E, 8, 2)`` plane points, whose convex hull for each light holds the ball's shadow from it.

    Args:
        emitters: ``(E, 3)`` light positions, each above the ball (``emitters[:, 2] > centre[2] +
            radius``: a light at or below its top throws an unbounded shadow); centre, radius: the
            ball (world, painting units).
    """
    corners = cube_corners(centre, radius)
    height = emitters[:, 2:]
    scale = height / (height - corners[:, 2])
    return emitters[:, None, :2] + scale[..., None] * (corners[:, :2] - emitters[:, None, :2])


def _pixel_spread(K: np.ndarray, R: np.ndarray, t: np.ndarray, points: np.ndarray) -> np.ndarray:
    """``(...)`` half the longer side of the image bounding box of each set of world points
    ``(..., N, 3)``, pixels; ``inf`` for a set with a point not in front of the camera."""
    flat = points.reshape(-1, 3)
    behind = ((flat @ R.T + t)[:, 2] <= 0).reshape(points.shape[:-1]).any(axis=-1)
    pixels = project(K, R, t, flat).reshape(*points.shape[:-1], 2)
    spread = (pixels.max(axis=-2) - pixels.min(axis=-2)).max(axis=-1) / 2
    return np.where(behind, math.inf, spread)


def ball_pixel_radius(K: np.ndarray, R: np.ndarray, t: np.ndarray, centre: np.ndarray, radius: float) -> float:
    """The radius, in pixels, a ball ``|X - centre| <= radius`` shows at in a camera's image.

    Measured as half the longer side of the image bounding box of its bounding cube's corners (at
    most ``sqrt(3)`` times the ball's own projected radius, never less); ``inf`` when the cube
    reaches behind the camera. The image's bounds are ignored (a ball partly out of view counts whole).

    Args:
        K, R: ``(3, 3)``; t: ``(3,)`` float64 camera (module conventions).
    """
    return float(_pixel_spread(K, R, t, cube_corners(centre, radius)))


def ball_shadow_pixel_radii(K: np.ndarray, R: np.ndarray, t: np.ndarray, emitters: np.ndarray,
                            centre: np.ndarray, radius: float) -> np.ndarray:
    """Like :func:`ball_pixel_radius` for the ball's shadows on the painting's plane, cast from
    point lights at ``emitters (E, 3)``: ``(E,)`` float64, the projected radius of each light's
    :func:`ball_shadow_corners` (``inf`` where the shadow is unbounded)."""
    emitters = np.asarray(emitters, dtype=np.float64).reshape(-1, 3)
    bounded = emitters[:, 2] > centre[2] + radius
    shadows = ball_shadow_corners(emitters[bounded], centre, radius)
    radii = np.full(len(emitters), math.inf)
    radii[bounded] = _pixel_spread(K, R, t, np.concatenate([shadows, np.zeros((*shadows.shape[:2], 1))], axis=2))
    return radii


def light_frustum(emitter: np.ndarray, outer_cone: float, receivers: np.ndarray, casters: np.ndarray,
                  margin: float = 0.0, reach: float = 0.0) -> np.ndarray | None:
    """The tightest perspective shadow-map frustum of a spot light aimed at the origin.

    The frustum is expressed in the light's own frame, :func:`look_at` ``(emitter)`` (OpenCV axes:
    x right, y down, z along the light's axis): ``[x0, x1, y0, y1, near, far]``, the window's
    bounds as tangents (``x / z``, ``y / z``) and the depth range along the axis. It holds

    * every receiver point (the points whose shadowing must be right; give the corners of a
      region or of a ball's :func:`cube_corners`), so every caster between the light and a
      receiver lies inside it too (on the segment from the light to that receiver);
    * laterally at most the light's cone ``|x|, |y| <= tan(outer_cone)``: outside it the light
      adds nothing, so no shadow there can change a pixel;
    * in depth, from the nearest caster or receiver (``near``) to the farthest receiver
      (``far``), so no caster is cut by the near plane; ``near`` is kept at least ``far / 1000``
      (a caster closer to the light than that would be inside the lamp).

    The window is widened by ``margin`` times its size on each side (for the texels a filtered
    shadow lookup reads around a point), then by ``reach`` (tangent units: how far a soft lookup
    searches, ``plan.soft_reach``), and ``far`` by ``margin`` times the depth range.

    Args:
        emitter: ``(3,)`` light position (world, painting units), not at the origin.
        outer_cone: the light's outer half-angle, rad, below pi / 2.
        receivers: ``(N, 3)`` world points.
        casters: ``(M, 4)`` balls ``(centre x, y, z, radius)`` that may cast shadows.
        margin: relative widening (>= 0).
        reach: absolute widening (>= 0), tangent units.

    Returns:
        ``(6,)`` float64, or ``None`` when a receiver is not in front of the light (no frustum
        of this kind holds them) or the receivers span no area inside the cone.
    """
    return light_frusta([emitter], [outer_cone], receivers, casters, margin, [reach])[0]


def light_frusta(emitters: Sequence[np.ndarray], outer_cones: Sequence[float], receivers: np.ndarray,
                 casters: np.ndarray, margin: float = 0.0, reaches: Sequence[float] = ()) -> list[np.ndarray | None]:
    """:func:`light_frustum` of each light ``emitters[k]`` ``(3,)``, ``outer_cones[k]``, ``reaches[k]``
    (default 0) over the same receivers and casters: each light's frame from :func:`look_at`, the
    rest in one set of array operations over the lights, each value the one the light gets alone
    (the same products, per light, and elementwise operations and exact minima and maxima)."""
    count = len(emitters)
    if count == 0:
        return []
    frames = [look_at(emitter) for emitter in emitters]
    Rt = np.stack([R.T for R, _ in frames])  # (L, 3, 3)
    t = np.stack([t for _, t in frames])[:, None, :]  # (L, 1, 3)
    cam = receivers @ Rt + t  # (L, N, 3)
    if cam.shape[1] == 0:
        return [None] * count
    depth = cam[..., 2]
    behind = (depth <= 0).any(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):  # lights with a receiver behind: not used
        tangents = cam[..., :2] / cam[..., 2:]
    limit = np.array([math.tan(cone) for cone in outer_cones])[:, None]  # math.tan, as each light alone
    low = np.minimum(np.maximum(tangents.min(axis=1), -limit), limit)  # (L, 2)
    high = np.minimum(np.maximum(tangents.max(axis=1), -limit), limit)
    empty = (high <= low).any(axis=1)
    reach = np.zeros(count) if len(reaches) == 0 else np.asarray(reaches, np.float64)
    pad = margin * (high - low) + reach[:, None]
    far = depth.max(axis=1)
    near = depth.min(axis=1)
    if len(casters):
        near = np.minimum(near, ((casters[:, :3] @ Rt + t)[..., 2] - casters[:, 3]).min(axis=1))
    near = np.maximum(near, far / 1000)
    far = far + margin * (far - near)
    frusta = np.stack([low[:, 0] - pad[:, 0], high[:, 0] + pad[:, 0], low[:, 1] - pad[:, 1], high[:, 1] + pad[:, 1],
                       near, far], axis=1)
    return [None if behind[k] or empty[k] else frusta[k] for k in range(count)]
