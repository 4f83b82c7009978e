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
    "clip_polygon",
    "is_reference_camera",
    "painting_pixel_area",
    "point_disagreement",
    "polygon_area",
    "shared_points",
    "visible_plane_points",
    "view_edges",
    "visible_halfplanes",
    "corner_pixels",
    "euler_rotation",
    "fit_points",
    "homographies_from_points",
    "intrinsics_from_fov",
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


def euler_rotation(angles: np.ndarray) -> np.ndarray:
    """The ``(3, 3)`` rotation of Euler angles ``angles (3,)`` (radians) about the world's x, then y, then
    z axis (``Rz Ry Rx``, Blender's ``XYZ`` order, as the paper's generator sets ``rotation=(rx, ry, rz)``)."""
    (cx, cy, cz), (sx, sy, sz) = np.cos(angles), np.sin(angles)
    x = np.array([[1.0, 0.0, 0.0], [0.0, cx, -sx], [0.0, sx, cx]])
    y = np.array([[cy, 0.0, sy], [0.0, 1.0, 0.0], [-sy, 0.0, cy]])
    z = np.array([[cz, -sz, 0.0], [sz, cz, 0.0], [0.0, 0.0, 1.0]])
    return z @ y @ x


def look_at(position: np.ndarray, target: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """World-to-camera ``R (3, 3)``, ``t (3,)`` (float64, OpenCV frame) of a camera at ``position``
    aimed at ``target`` (default: the origin), with world +y pointing up in the image.

    The camera must not look along world y (never the case for a camera above the painting).
    """
    position = np.asarray(position, dtype=np.float64)
    target = np.zeros(3) if target is None else np.asarray(target, dtype=np.float64)
    z = target - position
    z /= np.linalg.norm(z)
    x = _cross(z, WORLD_UP)
    x /= np.linalg.norm(x)
    y = _cross(z, x)
    rotation = np.stack([x, y, z])
    return rotation, -rotation @ position


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``np.cross`` of two ``(3,)`` float64 vectors, bit for bit (the same products and
    differences, in Python floats): a quarter of its cost, which is mostly its axis handling."""
    (a0, a1, a2), (b0, b1, b2) = a.tolist(), b.tolist()
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


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


def is_reference_camera(K: np.ndarray, R: np.ndarray, t: np.ndarray, image_size: tuple[int, int]) -> bool:
    """Whether ``K, R, t`` is, bit for bit, :func:`reference_camera` at its own height ``t[2]`` (the
    camera whose pixel (u, v) sees the painting's texel (u, v) at its centre)."""
    if not t[2] > 0:
        return False
    ref = reference_camera(image_size, float(t[2]))
    return all(np.array_equal(a, b) for a, b in zip((K, R, t), ref))


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
    """Scale homographies ``(..., 3, 3)`` to det = 1 (never by ``H[2, 2]``, which may be 0).

    The scale is the signed cube root of the determinant by NumPy's ``cbrt`` (on the CPU; no gradient
    flows through it), the same function for every element: ``torch.pow(|det|, 1 / 3)`` rounds
    otherwise in its vectorised loop than in its scalar one (1 ulp, in about 1 pair in 40 sequences),
    so a homography's value would depend on how many were normalised together
    (``tests/test_geometry.py``).
    """
    det = torch.linalg.det(H)
    scale = torch.as_tensor(np.cbrt(det.detach().cpu().numpy()), dtype=H.dtype, device=H.device)
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

    Each pair's fit reads only that pair's points, so a batch of sequences fitted in one call (one
    Kornia call instead of one per sequence: about 1 ms each on one core) gives the values each
    would get alone (``tests/test_geometry.py`` checks it bit for bit).

    It runs on one torch thread (torch's thread count is set to 1 for the call and put back): its
    tensors are tiny, and a second intra-op thread's synchronisation cost 12-20x the work (30-54 ms
    against 2.5-2.7 ms per 6-view sequence with the other core busy; ``torch.set_num_threads`` is a
    process-wide setting, so other threads' torch work also runs on one thread for those milliseconds).

    Args:
        points: ``(..., V, 4, 2)`` pixel coordinates of the same four plane points in each view of
            each sequence (leading dims: a batch of sequences).

    Returns:
        ``(..., V, V, 3, 3)`` float64 tensor, ``H[..., i, j]`` mapping view-i pixels to view-j pixels.

    Raises:
        RuntimeError: Kornia returned a non-finite homography (kornia < 0.9 does at times).
    """
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        return _homographies_from_points(points)
    finally:
        torch.set_num_threads(threads)


def _homographies_from_points(points: np.ndarray) -> torch.Tensor:
    pts = torch.as_tensor(points, dtype=torch.float64)
    batch, v = pts.shape[:-3], pts.shape[-3]
    src = pts[..., :, None, :, :].expand(*batch, v, v, 4, 2).reshape(-1, 4, 2)
    dst = pts[..., None, :, :, :].expand(*batch, v, v, 4, 2).reshape(-1, 4, 2)
    H = kornia.geometry.homography.find_homography_dlt(src, dst, solver="lu")
    if not torch.isfinite(H).all():  # kornia < 0.9's "lu" solved a singular normal system: NaN at times
        raise RuntimeError(f"kornia {kornia.__version__} fitted a non-finite homography to four plane points in front "
                           f"of every camera: sidar_torch needs kornia >= 0.9 (pip install 'kornia>=0.9')")
    H = normalize_det(H).reshape(*batch, v, v, 3, 3)
    H[..., torch.arange(v), torch.arange(v), :, :] = torch.eye(3, dtype=torch.float64)
    return H


def plane_induced_homographies(K: np.ndarray, R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """The analytic plane-induced homographies ``K_j (R_ij - t_ij n_i^T / d_i) K_i^{-1}`` (det = 1).

    ``R_ij, t_ij`` is the pose of camera j relative to camera i and ``n_i^T X + d_i = 0`` the
    painting's plane in camera i's frame (Hartley & Zisserman, result 13.1).

    Args:
        K, R: ``(..., V, 3, 3)``; t: ``(..., V, 3)`` float64 (leading dims: a batch of sequences).

    Returns:
        ``(..., V, V, 3, 3)`` float64 array.
    """
    R_ij = np.einsum("...jab,...icb->...ijac", R, R)  # R_j R_i^T
    t_ij = t[..., None, :, :] - np.einsum("...ijab,...ib->...ija", R_ij, t)  # t_j - R_ij t_i
    n = R @ PLANE_NORMAL  # (..., V, 3)
    d = -np.einsum("...ia,...ia->...i", n, t)
    euclid = R_ij - np.einsum("...ija,...ib->...ijab", t_ij, n) / d[..., :, None, None, None]
    H = np.einsum("...jab,...ijbc,...icd->...ijad", K, euclid, np.linalg.inv(K))
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
    return float(point_disagreements(H_a, H_b, points, where))


def point_disagreements(H_a: np.ndarray, H_b: np.ndarray, points: np.ndarray,
                        where: np.ndarray | None = None) -> np.ndarray:
    """:func:`point_disagreement` of each of a batch of sequences: ``H_a``, ``H_b`` ``(..., V, V, 3, 3)``,
    ``points`` ``(..., V, N, 2)``, ``where`` ``(..., V, V, N)``; returns ``(...)`` float64 pixels."""
    src = np.concatenate([points, np.ones((*points.shape[:-1], 1))], axis=-1)[..., :, None, :, :]  # (..., V, 1, N, 3)
    a = src @ np.swapaxes(H_a, -1, -2)  # (..., V, V, N, 3): H[i, j] applied to view i's points
    b = src @ np.swapaxes(H_b, -1, -2)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):  # unselected points may map to infinity
        distance = np.linalg.norm(a[..., :2] / a[..., 2:] - b[..., :2] / b[..., 2:], axis=-1)
    return np.max(distance, axis=(-3, -2, -1), where=True if where is None else where, initial=0.0)


def visible_plane_points(K: np.ndarray, R: np.ndarray, t: np.ndarray, image_size: tuple[int, int],
                         grid: int = 17) -> tuple[np.ndarray, np.ndarray]:
    """A ``grid x grid`` lattice over the painting, and which cameras see each of its points.

    Args:
        K, R: ``(..., V, 3, 3)``; t: ``(..., V, 3)`` float64 cameras (leading dims: a batch of sequences).
        image_size: ``(H, W)`` of the views and the painting.

    Returns:
        ``(..., V, N, 2)`` float64 pixel coordinates of the ``N = grid**2`` points in every view, and
        ``(..., V, N)`` bool: the point is in front of the camera and inside the image's outer edges.
    """
    h, w = image_size
    corners = plane_corners(image_size)
    u, v = (c.reshape(-1, 1) for c in np.meshgrid(np.linspace(0, 1, grid), np.linspace(0, 1, grid)))
    points = corners[0] + u * (corners[1] - corners[0]) + v * (corners[3] - corners[0])
    depth = np.einsum("...vab,nb->...vna", R, points)[..., 2] + t[..., :, None, 2]
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):  # points in the camera's plane
        pixels = project(K, R, t, points)
        inside = (depth > 0) & (pixels[..., 0] >= -0.5) & (pixels[..., 0] <= w - 0.5) \
            & (pixels[..., 1] >= -0.5) & (pixels[..., 1] <= h - 0.5)
    return pixels, inside


def shared_points(inside: np.ndarray) -> np.ndarray:
    """``(..., V, V, N)`` bool: point ``n`` is seen by both views ``i != j``, from ``inside (..., V, N)``."""
    v = inside.shape[-2]
    return inside[..., :, None, :] & inside[..., None, :, :] & ~np.eye(v, dtype=bool)[..., None]


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
    return view_edges(K, image_size) @ np.column_stack([R[:, 0], R[:, 1], t])


def view_edges(K: np.ndarray, image_size: tuple[int, int]) -> np.ndarray:
    """``(5, 3)``: camera-frame points ``X`` inside the view have ``a . X >= 0`` for every row ``a``
    (four image edges at the outer pixel borders, then the camera's front)."""
    h, w = image_size
    e3 = np.array([0.0, 0.0, 1.0])
    return np.stack([K[0] + 0.5 * e3, (w - 0.5) * e3 - K[0], K[1] + 0.5 * e3, (h - 0.5) * e3 - K[1], e3])


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
