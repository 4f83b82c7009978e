"""Pure camera and homography math, float64, no rendering.

Frames and conventions (the package's, written once here):

* World: the painting lies in the plane z = 0, centred at the origin, facing +z. Its image
  row 0 is at world y = +h/2 and column 0 at x = -w/2 (``w, h`` in painting units).
* Camera: OpenCV/Kornia frame (x right, y down, z forward). ``R, t`` map world to camera,
  so a world point ``X`` lands at pixel ``K (R X + t)`` (after division by the third entry).
* Pixels: Kornia's convention, the centre of the top-left pixel is (0, 0) and pixel (u, v) is
  column u, row v. The painting's outer corners are therefore at (-0.5, -0.5) and
  (W - 0.5, H - 0.5) in the reference view.
* ``H[i, j]`` maps view-i pixels to view-j pixels and is scaled to det = 1.
"""

from __future__ import annotations

import math

import kornia
import numpy as np
import torch

__all__ = [
    "ball_may_be_seen",
    "ball_pixel_radius",
    "ball_shadow_corners",
    "ball_shadow_pixel_radius",
    "cube_corners",
    "clip_polygon",
    "painting_mask",
    "painting_pixel_area",
    "point_disagreement",
    "polygon_area",
    "shadow_may_fall_on_ball",
    "shadow_may_reach",
    "shared_points",
    "visible_plane_points",
    "visible_halfplanes",
    "corner_pixels",
    "fit_points",
    "homographies_from_points",
    "intrinsics_from_fov",
    "light_frustum",
    "look_at",
    "normalize_det",
    "plane_corners",
    "plane_induced_homographies",
    "plane_size",
    "project",
    "reference_camera",
]

WORLD_UP = np.array([0.0, 1.0, 0.0])
PLANE_NORMAL = np.array([0.0, 0.0, 1.0])


def plane_size(image_size: tuple[int, int]) -> tuple[float, float]:
    """Painting ``(width, height)`` in painting units: shorter side 1, the image's aspect ratio.

    Args:
        image_size: ``(H, W)`` in pixels.
    """
    h, w = image_size
    return (w / h, 1.0) if w >= h else (1.0, h / w)


def plane_corners(image_size: tuple[int, int]) -> np.ndarray:
    """World corners of the painting, ``(4, 3)`` float64, in the order top-left, top-right,
    bottom-right, bottom-left of the image (matching :func:`corner_pixels`)."""
    w, h = plane_size(image_size)
    return np.array([[-w / 2, h / 2, 0], [w / 2, h / 2, 0], [w / 2, -h / 2, 0], [-w / 2, -h / 2, 0]])


FIT_RADIUS = 0.5
"""Largest half-diagonal (painting units) of the fitting square: it stays on the painting,
whose shorter side is 1."""


def fit_points(camera_centres: np.ndarray) -> np.ndarray:
    """Four painting-plane points ``(4, 3)`` in front of every camera, for fitting homographies.

    A square centred on the origin, as large as the cameras allow: half-diagonal
    ``r = min(FIT_RADIUS, min_k |C_k|^2 / (2 |C_k,xy|))`` for camera centres ``C_k`` (world, painting
    units) aimed at the origin. A plane point ``X`` (``|X| <= r``) then lies at depth
    ``(|C|^2 - X . C) / |C| >= |C| / 2`` in every camera, so no fit point is behind a camera or
    near its horizon (the painting's own corners can be, for a camera close to a wide painting).
    Only a camera's sideways offset ``C_xy`` limits the square: one straight above the painting
    sees every plane point in front of it.

    Why as large as allowed: the DLT is exact on its four points up to their round-off
    (``~1e-16 |x|`` px), and its error elsewhere grows with the ratio of the visible painting's
    extent to the fitted points' spread in each view. A square sized by the nearest camera alone
    (the earlier rule, half-diagonal ``0.35 min |C|``) spans a fraction of a pixel in a far view
    when another camera is close, and extrapolating from it cost up to 2.6e-6 px at points both
    views see (``tests/test_hard_cases.py``).

    Args:
        camera_centres: ``(V, 3)`` world positions of the cameras (z > 0), aimed at the origin.
    """
    centres = np.asarray(camera_centres, dtype=np.float64)
    sideways = np.linalg.norm(centres[:, :2], axis=1)
    squared = np.einsum("ka,ka->k", centres, centres)
    limit = np.divide(squared, 2 * sideways, out=np.full_like(squared, np.inf), where=sideways > 0)
    half = min(FIT_RADIUS, float(limit.min())) / math.sqrt(2)
    return np.array([[-half, half, 0], [half, half, 0], [half, -half, 0], [-half, -half, 0]])


def corner_pixels(image_size: tuple[int, int]) -> np.ndarray:
    """The image's outer corners in Kornia pixels, ``(4, 2)`` float64: (-0.5, -0.5) ... ."""
    h, w = image_size
    return np.array([[-0.5, -0.5], [w - 0.5, -0.5], [w - 0.5, h - 0.5], [-0.5, h - 0.5]])


def intrinsics_from_fov(fov_deg: float, image_size: tuple[int, int]) -> np.ndarray:
    """Pinhole intrinsics ``(3, 3)`` float64 with square pixels and the principal point at the image centre.

    Args:
        fov_deg: field of view across the longer image side, degrees (Blender's sensor-fit auto).
        image_size: ``(H, W)`` in pixels.
    """
    h, w = image_size
    f = max(h, w) / 2 / math.tan(math.radians(fov_deg) / 2)
    return np.array([[f, 0, (w - 1) / 2], [0, f, (h - 1) / 2], [0, 0, 1.0]])


def look_at(position: np.ndarray, target: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """World-to-camera ``R (3, 3)``, ``t (3,)`` (float64, OpenCV frame) of a camera at ``position``
    aimed at ``target`` (default: the origin), with world +y pointing up in the image.

    The camera must not look along world y (never the case for a camera above the painting).
    """
    position = np.asarray(position, dtype=np.float64)
    target = np.zeros(3) if target is None else np.asarray(target, dtype=np.float64)
    z = target - position
    z /= np.linalg.norm(z)
    x = np.cross(z, WORLD_UP)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    rotation = np.stack([x, y, z])
    return rotation, -rotation @ position


def reference_camera(image_size: tuple[int, int], distance: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The fronto-parallel camera whose view is exactly the painting: ``K, R, t`` (float64).

    Pixel (u, v) of this view sees the painting's texel (u, v) at its centre, so the label
    is the painting itself.

    Args:
        image_size: ``(H, W)`` in pixels.
        distance: camera height above the painting, painting units.
    """
    h, w = image_size
    f = distance * w / plane_size(image_size)[0]
    K = np.array([[f, 0, (w - 1) / 2], [0, f, (h - 1) / 2], [0, 0, 1.0]])
    R, t = look_at(np.array([0.0, 0.0, distance]))
    return K, R, t


def project(K: np.ndarray, R: np.ndarray, t: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Project world points with a batch of cameras.

    Args:
        K, R: ``(..., 3, 3)``; t: ``(..., 3)``; points: ``(N, 3)`` world points.

    Returns:
        ``(..., N, 2)`` float64 pixel coordinates (Kornia convention).
    """
    cam = np.einsum("...ij,nj->...ni", R, points) + t[..., None, :]
    pix = np.einsum("...ij,...nj->...ni", K, cam)
    return pix[..., :2] / pix[..., 2:]


def normalize_det(H: torch.Tensor) -> torch.Tensor:
    """Scale homographies ``(..., 3, 3)`` to det = 1 (never by ``H[2, 2]``, which may be 0)."""
    det = torch.linalg.det(H)
    scale = torch.sign(det) * det.abs().pow(1.0 / 3.0)
    return H / scale[..., None, None]


def homographies_from_points(points: np.ndarray) -> torch.Tensor:
    """Every pairwise homography from four plane points as each view sees them.

    Kornia's normalised DLT (``find_homography_dlt``) on all ``V * V`` ordered pairs in one
    batch, in float64, then scaled to det = 1; the diagonal is set to exactly I.

    The solver is ``"lu"``, Kornia's minimal four-point path: a pivoted LU of the 8 x 9 design
    matrix, gauge fixed by the null vector's largest entry. ``"svd"`` takes the null vector of
    ``A^T A``, which squares the design matrix's condition number: when the points are nearly
    collinear in one view it was off, at points both views see, by 2.6e-4 px for a camera
    tilted 89.9 degrees and 7e-2 px at 89.99 (``max_tilt_deg`` allows both), where ``"lu"`` is
    off by 5e-8 px and 4e-5 px (``tests/test_hard_cases.py``).

    Args:
        points: ``(V, 4, 2)`` pixel coordinates of the same four plane points in each view.

    Returns:
        ``(V, V, 3, 3)`` float64 tensor, ``H[i, j]`` mapping view-i pixels to view-j pixels.
    """
    pts = torch.as_tensor(points, dtype=torch.float64)
    v = pts.shape[0]
    src = pts[:, None].expand(v, v, 4, 2).reshape(-1, 4, 2)
    dst = pts[None, :].expand(v, v, 4, 2).reshape(-1, 4, 2)
    H = kornia.geometry.homography.find_homography_dlt(src, dst, solver="lu")
    H = normalize_det(H).reshape(v, v, 3, 3)
    H[torch.arange(v), torch.arange(v)] = torch.eye(3, dtype=torch.float64)
    return H


def plane_induced_homographies(K: np.ndarray, R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """The analytic plane-induced homographies ``K_j (R_ij - t_ij n_i^T / d_i) K_i^{-1}`` (det = 1).

    ``R_ij, t_ij`` is the pose of camera j relative to camera i and ``n_i^T X + d_i = 0`` the
    painting's plane in camera i's frame (Hartley & Zisserman, result 13.1).

    Args:
        K, R: ``(V, 3, 3)``; t: ``(V, 3)`` float64.

    Returns:
        ``(V, V, 3, 3)`` float64 array.
    """
    R_ij = np.einsum("jab,icb->ijac", R, R)  # R_j R_i^T
    t_ij = t[None, :] - np.einsum("ijab,ib->ija", R_ij, t)  # t_j - R_ij t_i
    n = R @ PLANE_NORMAL  # (V, 3)
    d = -np.einsum("ia,ia->i", n, t)
    euclid = R_ij - np.einsum("ija,ib->ijab", t_ij, n) / d[:, None, None, None]
    H = np.einsum("jab,ijbc,icd->ijad", K, euclid, np.linalg.inv(K))
    return normalize_det(torch.from_numpy(H)).numpy()


def point_disagreement(H_a: np.ndarray, H_b: np.ndarray, points: np.ndarray, where: np.ndarray | None = None) -> float:
    """Largest distance in pixels between where two sets of homographies send the same points.

    Args:
        H_a, H_b: ``(V, V, 3, 3)`` homographies (any scale), ``H[i, j]`` from view i to view j.
        points: ``(V, N, 2)`` the points in each view's pixels.
        where: ``(V, V, N)`` bool, which points to compare for each pair (default: all).

    Returns:
        The largest distance in view-j pixels (0 when ``where`` selects nothing).
    """
    src = np.concatenate([points, np.ones((*points.shape[:2], 1))], axis=2)
    a = np.einsum("ijab,inb->ijna", H_a, src)
    b = np.einsum("ijab,inb->ijna", H_b, src)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):  # unselected points may map to infinity
        distance = np.linalg.norm(a[..., :2] / a[..., 2:] - b[..., :2] / b[..., 2:], axis=-1)
    return float(distance.max() if where is None else distance[where].max(initial=0.0))


def visible_plane_points(K: np.ndarray, R: np.ndarray, t: np.ndarray, image_size: tuple[int, int],
                         grid: int = 17) -> tuple[np.ndarray, np.ndarray]:
    """A ``grid x grid`` lattice over the painting, and which cameras see each of its points.

    Args:
        K, R: ``(V, 3, 3)``; t: ``(V, 3)`` float64 cameras.
        image_size: ``(H, W)`` of the views and the painting.

    Returns:
        ``(V, N, 2)`` float64 pixel coordinates of the ``N = grid**2`` points in every view, and
        ``(V, N)`` bool: the point is in front of the camera and inside the image's outer edges.
    """
    h, w = image_size
    corners = plane_corners(image_size)
    u, v = (c.reshape(-1, 1) for c in np.meshgrid(np.linspace(0, 1, grid), np.linspace(0, 1, grid)))
    points = corners[0] + u * (corners[1] - corners[0]) + v * (corners[3] - corners[0])
    depth = np.einsum("vab,nb->vna", R, points)[..., 2] + t[:, None, 2]
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):  # points in the camera's plane
        pixels = project(K, R, t, points)
        inside = (depth > 0) & (pixels[..., 0] >= -0.5) & (pixels[..., 0] <= w - 0.5) \
            & (pixels[..., 1] >= -0.5) & (pixels[..., 1] <= h - 0.5)
    return pixels, inside


def shared_points(inside: np.ndarray) -> np.ndarray:
    """``(V, V, N)`` bool: point ``n`` is seen by both views ``i != j``, from ``inside (V, N)``."""
    v = len(inside)
    return inside[:, None] & inside[None, :] & ~np.eye(v, dtype=bool)[..., None]


def visible_halfplanes(K: np.ndarray, R: np.ndarray, t: np.ndarray, image_size: tuple[int, int]) -> np.ndarray:
    """The part of the painting's plane a camera sees, as half-planes ``a . (x, y, 1) >= 0``.

    A plane point ``(x, y, 0)`` is at camera point ``M (x, y, 1)`` with ``M = [r_1, r_2, t]``; it
    is seen when it is in front of the camera and its pixel lies within the image's outer
    edges, ``-0.5 <= u <= W - 0.5`` and ``-0.5 <= v <= H - 0.5`` (Kornia pixels).

    Args:
        K, R: ``(3, 3)``; t: ``(3,)`` float64 camera.
        image_size: ``(H, W)`` in pixels.

    Returns:
        ``(5, 3)`` float64 half-plane coefficients: four image edges and the camera's front.
    """
    return _view_edges(K, image_size) @ np.column_stack([R[:, 0], R[:, 1], t])


def _view_edges(K: np.ndarray, image_size: tuple[int, int]) -> np.ndarray:
    """``(5, 3)``: camera-frame points ``X`` inside the view have ``a . X >= 0`` for every row ``a``
    (four image edges at the outer pixel borders, then the camera's front)."""
    h, w = image_size
    e3 = np.array([0.0, 0.0, 1.0])
    return np.stack([K[0] + 0.5 * e3, (w - 0.5) * e3 - K[0], K[1] + 0.5 * e3, (h - 0.5) * e3 - K[1], e3])


def ball_may_be_seen(K: np.ndarray, R: np.ndarray, t: np.ndarray, image_size: tuple[int, int],
                     centre: np.ndarray, radius: float) -> bool:
    """Whether a ball ``|X - centre| <= radius`` (world) may show in a camera's image.

    Conservative: ``False`` only when the ball lies wholly outside one of the view's bounding
    planes (the four image edges and the camera's front).
    """
    edges = _view_edges(K, image_size)
    distance = edges @ (R @ centre + t) / np.linalg.norm(edges, axis=1)
    return bool((distance >= -radius).all())


def clip_polygon(polygon: np.ndarray, halfplanes: np.ndarray) -> np.ndarray:
    """Intersect a convex polygon with half-planes (Sutherland-Hodgman).

    Args:
        polygon: ``(N, 2)`` vertices in order.
        halfplanes: ``(M, 3)``, keeping points with ``a . (x, y, 1) >= 0``.

    Returns:
        ``(K, 2)`` vertices of the intersection (``K = 0`` when it is empty).
    """
    for a in halfplanes:
        if len(polygon) == 0:
            break
        side = polygon @ a[:2] + a[2]
        kept = []
        for k in range(len(polygon)):
            p, q, sp, sq = polygon[k - 1], polygon[k], side[k - 1], side[k]
            if (sp >= 0) != (sq >= 0):
                kept.append(p + (q - p) * (sp / (sp - sq)))
            if sq >= 0:
                kept.append(q)
        polygon = np.array(kept).reshape(-1, 2)
    return polygon


def polygon_area(polygon: np.ndarray) -> float:
    """Area of a simple polygon ``(N, 2)`` (shoelace formula), 0 for fewer than 3 vertices."""
    if len(polygon) < 3:
        return 0.0
    x, y = polygon[:, 0], polygon[:, 1]
    return 0.5 * abs(float(x @ np.roll(y, -1) - y @ np.roll(x, -1)))


def painting_pixel_area(K: np.ndarray, R: np.ndarray, t: np.ndarray, image_size: tuple[int, int],
                        others: tuple[np.ndarray, ...] = ()) -> float:
    """Pixels of a camera's image covered by the painting, optionally only where other cameras see it too.

    The painting's rectangle is clipped to the camera's visible half-planes (and to each of
    ``others``, half-planes from :func:`visible_halfplanes`), projected into the image and
    measured: exact for the pinhole model.

    Args:
        K, R: ``(3, 3)``; t: ``(3,)`` float64 camera.
        image_size: ``(H, W)`` of the image and of the painting (same aspect).
        others: ``(5, 3)`` half-planes of further cameras.
    """
    region = plane_corners(image_size)[:, :2]
    for halfplanes in (visible_halfplanes(K, R, t, image_size), *others):
        region = clip_polygon(region, halfplanes)
    if len(region) < 3:
        return 0.0
    return polygon_area(project(K, R, t, np.column_stack([region, np.zeros(len(region))])))


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


def painting_mask(K: np.ndarray, R: np.ndarray, t: np.ndarray, image_size: tuple[int, int]) -> np.ndarray:
    """``(H, W)`` bool: True at pixels whose centre does not see the painting (background).

    The camera ray through pixel centre ``(u, v)`` (Kornia pixels, integer centres) meets the
    plane at homogeneous plane point ``p = M^-1 K^-1 (u, v, 1)``, ``M = [r_1, r_2, t]`` (so
    ``(x, y) = p[:2] / p[2]``), in front of the camera when ``p[2] > 0``; it sees the painting when
    moreover ``|x| <= w / 2`` and ``|y| <= h / 2``. Along a row ``p`` is linear in ``u``, so each
    condition holds on a half-line of ``u`` and the seen columns are an interval: the work is
    per row, and exact up to float64 rounding (the same plane geometry as the homographies).
    Nothing is near-clipped: the renderer's near plane lies in front of every painting point in
    view (``render.renderer._clip_range``).

    Args:
        K, R: ``(3, 3)``; t: ``(3,)`` float64 camera.
        image_size: ``(H, W)`` in pixels, of the image and of the painting (same aspect).
    """
    h, w = image_size
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


def ball_shadow_corners(emitter: np.ndarray, centre: np.ndarray, radius: float) -> np.ndarray | None:
    """The ball's bounding-cube corners projected from a point light onto the plane ``z = 0``,
    ``(8, 2)`` plane points whose convex hull holds the ball's shadow; ``None`` when the ball
    reaches the light's height (its shadow is then unbounded).

    Args:
        emitter: ``(3,)`` light position, ``z > 0``; centre, radius: the ball (world, painting units).
    """
    if centre[2] + radius >= emitter[2]:
        return None
    corners = cube_corners(centre, radius)
    scale = emitter[2] / (emitter[2] - corners[:, 2])
    return emitter[:2] + scale[:, None] * (corners[:, :2] - emitter[:2])


def _pixel_spread(K: np.ndarray, R: np.ndarray, t: np.ndarray, points: np.ndarray) -> float:
    """Half the longer side of the image bounding box of world points ``(N, 3)``, pixels; ``inf``
    when a point is not in front of the camera."""
    if ((points @ R.T + t)[:, 2] <= 0).any():
        return math.inf
    pixels = project(K, R, t, points)
    return float((pixels.max(axis=0) - pixels.min(axis=0)).max()) / 2


def ball_pixel_radius(K: np.ndarray, R: np.ndarray, t: np.ndarray, centre: np.ndarray, radius: float) -> float:
    """The radius, in pixels, a ball ``|X - centre| <= radius`` shows at in a camera's image.

    Measured as half the longer side of the image bounding box of its bounding cube's corners (at
    most ``sqrt(3)`` times the ball's own projected radius, never less); ``inf`` when the cube
    reaches behind the camera. The image's bounds are ignored (a ball partly out of view counts whole).

    Args:
        K, R: ``(3, 3)``; t: ``(3,)`` float64 camera (module conventions).
    """
    return _pixel_spread(K, R, t, cube_corners(centre, radius))


def ball_shadow_pixel_radius(K: np.ndarray, R: np.ndarray, t: np.ndarray, emitter: np.ndarray,
                             centre: np.ndarray, radius: float) -> float:
    """Like :func:`ball_pixel_radius` for the ball's shadow on the painting's plane, cast from a
    point light at ``emitter (3,)``: the projected radius of its :func:`ball_shadow_corners`
    (``inf`` when the shadow is unbounded)."""
    shadow = ball_shadow_corners(emitter, centre, radius)
    if shadow is None:
        return math.inf
    return _pixel_spread(K, R, t, np.column_stack([shadow, np.zeros(len(shadow))]))


def light_frustum(emitter: np.ndarray, outer_cone: float, receivers: np.ndarray, casters: np.ndarray,
                  margin: float = 0.0) -> np.ndarray | None:
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
    shadow lookup reads around a point), and ``far`` by ``margin`` times the depth range.

    Args:
        emitter: ``(3,)`` light position (world, painting units), not at the origin.
        outer_cone: the light's outer half-angle, rad, below pi / 2.
        receivers: ``(N, 3)`` world points.
        casters: ``(M, 4)`` balls ``(centre x, y, z, radius)`` that may cast shadows.
        margin: relative widening (>= 0).

    Returns:
        ``(6,)`` float64, or ``None`` when a receiver is not in front of the light (no frustum
        of this kind holds them) or the receivers span no area inside the cone.
    """
    R, t = look_at(emitter)
    cam = receivers @ R.T + t
    if len(cam) == 0 or (cam[:, 2] <= 0).any():
        return None
    tangents = cam[:, :2] / cam[:, 2:]
    limit = math.tan(outer_cone)
    low = np.clip(tangents.min(axis=0), -limit, limit)
    high = np.clip(tangents.max(axis=0), -limit, limit)
    if (high <= low).any():
        return None
    pad = margin * (high - low)
    far = float(cam[:, 2].max())
    depths = [float(cam[:, 2].min())]
    if len(casters):
        depths.append(float(((casters[:, :3] @ R.T + t)[:, 2] - casters[:, 3]).min()))
    near = max(min(depths), far / 1000)
    far += margin * (far - near)
    return np.array([low[0] - pad[0], high[0] + pad[0], low[1] - pad[1], high[1] + pad[1], near, far])
