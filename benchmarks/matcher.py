"""How a classical matcher fares on a sequence: SIFT keypoints on the painting, Lowe's ratio test and a
RANSAC homography for every pair of views, scored against the true homography.

For each view the OpenCV SIFT detector (``cv2.SIFT_create()``, default parameters) runs on the
view's grey levels; only keypoints whose pixel (the keypoint's position rounded) shows the painting
(mask 0) are kept. For each pair ``i < j`` the keypoints of view ``i`` are matched to those of view
``j`` by the ratio test (nearest descriptor closer than :data:`RATIO` times the second nearest), and
``cv2.findHomography(..., cv2.RANSAC, RANSAC_PX)`` estimates the homography from the matches (RANSAC
seeded by ``cv2.setRNGSeed(0)`` before each call, so the statistics are deterministic). A pair's
*error* is the mean distance, in view ``j``'s pixels, between the painting's four corners in view ``i``
mapped by the estimated and by the true homography (the painting's corners: view 0's corner pixels,
view 0 showing exactly the painting in ours and in the paper's sequences, carried into view ``i`` by the
true ``H[0, i]``; the homography holds on the painting's plane only, and the image corners of a steep
view lie far off the painting, where an estimate fitted on it is extrapolated); a pair *succeeds* when the error is below
:data:`SUCCESS_PX`, and fails (error ``inf``) with fewer than :data:`MIN_MATCHES` matches or no
estimate.

Pixel convention (Kornia's, which is also OpenCV's for keypoints): pixel centres at integer
coordinates, the top-left pixel at (0, 0), y down; ``H[i, j]`` maps view ``i``'s pixels to view
``j``'s, ``[x_j, y_j, 1] ~ H[i, j] @ [x_i, y_i, 1]``.
"""

from __future__ import annotations

import dataclasses
import itertools

import cv2
import numpy as np

RATIO = 0.8
"""Lowe's ratio test: a match is kept when its descriptor distance is below this fraction of the
distance to the second nearest descriptor."""

RANSAC_PX = 3.0
"""RANSAC's reprojection threshold (pixels) in ``cv2.findHomography``."""

MIN_MATCHES = 4
"""Fewest matches a homography is estimated from (fewer: the pair fails)."""

SUCCESS_PX = 3.0
"""A pair succeeds when its corner error (pixels) is below this."""


@dataclasses.dataclass(frozen=True)
class MatcherStats:
    """Matcher statistics of one sequence of ``V`` views and its ``P = V (V - 1) / 2`` pairs ``i < j``
    (in the order of ``itertools.combinations(range(V), 2)``).

    Attributes:
        keypoints: ``(V,)`` int64, SIFT keypoints on the painting per view.
        matches: ``(P,)`` int64, ratio-test matches per pair.
        errors: ``(P,)`` float64, corner error per pair in pixels (``inf``: no estimate).
    """

    keypoints: np.ndarray
    matches: np.ndarray
    errors: np.ndarray

    @property
    def success(self) -> np.ndarray:
        """``(P,)`` bool: the pairs whose error is below :data:`SUCCESS_PX`."""
        return self.errors < SUCCESS_PX

    @property
    def success_rate(self) -> float:
        """Fraction of the pairs that succeed."""
        return float(self.success.mean())

    @property
    def median_error(self) -> float:
        """Median error (pixels) of the pairs that succeed; NaN when none does."""
        return float(np.median(self.errors[self.success])) if self.success.any() else float("nan")


def painting_features(view: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """SIFT keypoints and descriptors of one view, those on the painting only.

    Args:
        view: ``(H, W, 3)`` uint8 RGB (converted to grey with ``cv2.COLOR_RGB2GRAY``).
        mask: ``(H, W)`` bool, True where the painting is not visible.

    Returns:
        ``points`` ``(K, 2)`` float32 ``(x, y)`` pixel positions (Kornia convention) and ``descriptors``
        ``(K, 128)`` float32, for the ``K`` keypoints whose rounded position has ``mask`` False.
    """
    if mask.shape != view.shape[:2]:
        raise ValueError(f"mask {mask.shape} and view {view.shape} must share (H, W)")
    keypoints, descriptors = cv2.SIFT_create().detectAndCompute(cv2.cvtColor(view, cv2.COLOR_RGB2GRAY), None)
    points = np.array([k.pt for k in keypoints], np.float32).reshape(-1, 2)
    if descriptors is None:
        descriptors = np.zeros((0, 128), np.float32)
    h, w = mask.shape
    columns = np.clip(np.round(points[:, 0]).astype(int), 0, w - 1)
    rows = np.clip(np.round(points[:, 1]).astype(int), 0, h - 1)
    on_painting = ~mask[rows, columns]
    return points[on_painting], descriptors[on_painting]


def ratio_matches(descriptors_i: np.ndarray, descriptors_j: np.ndarray) -> np.ndarray:
    """Lowe's ratio-test matches from view ``i``'s descriptors to view ``j``'s.

    Args:
        descriptors_i, descriptors_j: ``(K_i, 128)`` and ``(K_j, 128)`` float32 SIFT descriptors.

    Returns:
        ``(M, 2)`` int64 index pairs ``(k_i, k_j)``: each descriptor of ``i`` whose nearest descriptor
        of ``j`` (L2) is closer than :data:`RATIO` times the second nearest (none when ``K_j < 2``).
    """
    if len(descriptors_i) == 0 or len(descriptors_j) < 2:
        return np.zeros((0, 2), np.int64)
    neighbours = cv2.BFMatcher(cv2.NORM_L2).knnMatch(descriptors_i, descriptors_j, k=2)
    kept = [(best.queryIdx, best.trainIdx) for best, second in neighbours if best.distance < RATIO * second.distance]
    return np.array(kept, np.int64).reshape(-1, 2)


def image_corners(size: tuple[int, int]) -> np.ndarray:
    """The four corner pixels ``(4, 2)`` float64 ``(x, y)`` of an image of ``size = (H, W)``: ``(0, 0),
    (W - 1, 0), (W - 1, H - 1), (0, H - 1)`` (Kornia convention)."""
    h, w = size
    return np.array([[0, 0], [w - 1, 0], [w - 1, h - 1], [0, h - 1]], np.float64)


def map_points(H: np.ndarray, points: np.ndarray) -> np.ndarray:
    """``points (N, 2)`` mapped by the homography ``H (3, 3)``: ``(N, 2)`` float64, ``inf`` where it
    sends a point to infinity (a point beyond the horizon is mapped all the same: homographies are
    projective maps of the image plane)."""
    p = np.asarray(H, np.float64) @ np.concatenate([points, np.ones((len(points), 1))], axis=1).T
    with np.errstate(divide="ignore", invalid="ignore"):
        mapped = p[:2] / p[2]
    return np.where(p[2] == 0, np.inf, mapped).T


def corner_error(H_estimated: np.ndarray, H_true: np.ndarray, corners: np.ndarray) -> float:
    """Mean distance (pixels of the target view) between ``corners (4, 2)`` of the source view mapped by
    two ``(3, 3)`` homographies (``inf`` when either sends a corner to infinity)."""
    a, b = map_points(H_estimated, corners), map_points(H_true, corners)
    if not (np.isfinite(a).all() and np.isfinite(b).all()):
        return float("inf")
    return float(np.linalg.norm(a - b, axis=1).mean())


def estimate_homography(points_i: np.ndarray, points_j: np.ndarray) -> np.ndarray | None:
    """RANSAC homography ``(3, 3)`` float64 mapping ``points_i`` ``(M, 2)`` to ``points_j`` ``(M, 2)``
    (threshold :data:`RANSAC_PX`, RNG seeded to 0 first); None with fewer than :data:`MIN_MATCHES`
    points or when OpenCV finds none."""
    if len(points_i) < MIN_MATCHES:
        return None
    cv2.setRNGSeed(0)
    H, _ = cv2.findHomography(points_i, points_j, cv2.RANSAC, RANSAC_PX)
    return H


def matcher_stats(views: np.ndarray, masks: np.ndarray, homographies: np.ndarray) -> MatcherStats:
    """Matcher statistics of one sequence.

    Args:
        views: ``(V, H, W, 3)`` uint8 RGB.
        masks: ``(V, H, W)`` bool, True where the painting is not visible.
        homographies: ``(V, V, 3, 3)`` true homographies, ``homographies[i, j]`` maps view ``i``'s
            pixels to view ``j``'s (Kornia convention); only ``i <= j`` is read. View 0 must show
            exactly the painting (its corners are the painting's).
    """
    if views.ndim != 4 or masks.shape != views.shape[:3] or homographies.shape[:2] != (len(views),) * 2:
        raise ValueError(f"views {views.shape}, masks {masks.shape} and homographies {homographies.shape} "
                         "must be (V, H, W, 3), (V, H, W) and (V, V, 3, 3)")
    features = [painting_features(view, mask) for view, mask in zip(views, masks)]
    painting_corners = [map_points(homographies[0, i], image_corners(views.shape[1:3])) for i in range(len(views))]
    matches, errors = [], []
    for i, j in itertools.combinations(range(len(views)), 2):
        (points_i, descriptors_i), (points_j, descriptors_j) = features[i], features[j]
        pairs = ratio_matches(descriptors_i, descriptors_j)
        H = estimate_homography(points_i[pairs[:, 0]], points_j[pairs[:, 1]])
        matches.append(len(pairs))
        errors.append(float("inf") if H is None else corner_error(H, homographies[i, j], painting_corners[i]))
    return MatcherStats(np.array([len(p) for p, _ in features], np.int64), np.array(matches, np.int64),
                        np.array(errors, np.float64))
