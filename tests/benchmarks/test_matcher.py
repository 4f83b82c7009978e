"""The matcher statistics (``benchmarks/matcher.py``) on pairs whose true homography is known, and the
realism report's occluder and anchor readers (``benchmarks/realism.py``)."""

import cv2
import numpy as np
import pytest
from scipy import ndimage

from benchmarks import matcher, realism

SIZE = (192, 256)

MOVED = np.array([[0.95, 0.04, 6.0], [-0.03, 1.02, -4.0], [2e-5, -1e-5, 1.0]])
"""View 0 -> view 1 pixels: a mild rotation, scale, shift and perspective."""


def painting(seed=0):
    """``(H, W, 3)`` uint8: a textured painting (blobs at several scales and sharp-edged blocks)."""
    rng = np.random.default_rng(seed)
    blobs = sum(ndimage.gaussian_filter(rng.random((*SIZE, 3)), s) * s for s in (1.5, 3.0, 6.0))
    blocks = rng.random((SIZE[0] // 16, SIZE[1] // 16, 3)).repeat(16, 0).repeat(16, 1)
    image = 0.6 * (blobs - blobs.min()) / np.ptp(blobs) + 0.4 * blocks
    return (255 * image).round().astype(np.uint8)


def pair(H=MOVED):
    """Views ``(2, H, W, 3)`` uint8 (the painting and its warp by ``H``), masks ``(2, H, W)`` bool (True
    off the warped painting) and the true homographies ``(2, 2, 3, 3)``."""
    view0 = painting()
    view1 = cv2.warpPerspective(view0, H, SIZE[::-1], flags=cv2.INTER_LINEAR)
    covered = cv2.warpPerspective(np.ones(SIZE, np.uint8), H, SIZE[::-1], flags=cv2.INTER_NEAREST)
    homographies = np.array([[np.eye(3), H], [np.linalg.inv(H), np.eye(3)]])
    return np.stack([view0, view1]), np.stack([np.zeros(SIZE, bool), covered == 0]), homographies


def test_a_warped_textured_pair_is_matched_within_a_pixel():
    views, masks, homographies = pair()
    stats = matcher.matcher_stats(views, masks, homographies)
    assert (stats.keypoints > 50).all() and stats.matches[0] > 20
    assert stats.errors[0] < 1.0 and stats.success.tolist() == [True]
    assert stats.success_rate == 1.0 and stats.median_error == stats.errors[0]
    again = matcher.matcher_stats(views, masks, homographies)  # RANSAC is seeded: the same figures
    assert np.array_equal(again.errors, stats.errors) and np.array_equal(again.matches, stats.matches)


def test_a_wrong_true_homography_makes_the_pair_fail():
    views, masks, homographies = pair()
    homographies[0, 1] = homographies[0, 1] @ np.array([[1.0, 0, 5], [0, 1, 0], [0, 0, 1]])  # 5 px off
    stats = matcher.matcher_stats(views, masks, homographies)
    assert 4 < stats.errors[0] < 6 and not stats.success[0]
    assert stats.success_rate == 0 and np.isnan(stats.median_error)


def test_a_fully_masked_view_has_no_keypoints_no_matches_and_fails():
    views, masks, homographies = pair()
    masks[1] = True
    stats = matcher.matcher_stats(views, masks, homographies)
    assert stats.keypoints[1] == 0 and stats.matches[0] == 0 and stats.errors[0] == np.inf


def test_keypoints_under_the_mask_are_dropped():
    view = painting(1)
    everywhere = len(matcher.painting_features(view, np.zeros(SIZE, bool))[0])
    left = np.zeros(SIZE, bool)
    left[:, : SIZE[1] // 2] = True
    points, descriptors = matcher.painting_features(view, left)
    assert 0 < len(points) < everywhere and len(descriptors) == len(points)
    assert (points[:, 0] >= SIZE[1] // 2 - 0.5).all()


def test_every_pair_of_three_views_is_scored_in_order():
    views, masks, homographies = pair()
    blank = np.zeros((1, *SIZE, 3), np.uint8)  # a uniform view: no keypoints at all
    H = np.tile(np.eye(3), (3, 3, 1, 1))
    H[:2, :2] = homographies
    stats = matcher.matcher_stats(np.concatenate([views, blank]), np.concatenate([masks, np.zeros((1, *SIZE), bool)]),
                                  H)
    assert stats.keypoints[2] == 0 and stats.matches[1:].tolist() == [0, 0]
    assert stats.success.tolist() == [True, False, False] and stats.success_rate == pytest.approx(1 / 3)


def test_corner_error_is_the_mean_corner_distance():
    corners = matcher.image_corners(SIZE)
    shifted = np.array([[1.0, 0, 3], [0, 1, 4], [0, 0, 1]])
    assert matcher.corner_error(shifted, np.eye(3), corners) == pytest.approx(5.0)
    scaled = np.diag([2.0, 2.0, 1.0])  # corners (0, 0) unmoved, the other three moved by W-1, H-1, both
    h, w = SIZE
    expected = ((w - 1) + (h - 1) + np.hypot(w - 1, h - 1)) / 4
    assert matcher.corner_error(scaled, np.eye(3), corners) == pytest.approx(expected)
    horizon = np.array([[1.0, 0, 0], [0, 1, 0], [-1 / (w - 1), 0, 1]])  # sends x = W - 1 to infinity
    assert matcher.corner_error(horizon, np.eye(3), corners) == np.inf
    beyond = np.array([[1.0, 0, 0], [0, 1, 0], [-1 / 100, 0, 1]])  # w < 0 beyond x = 100: still mapped
    assert matcher.corner_error(beyond, beyond, corners) == 0


def test_the_error_is_measured_at_the_paintings_corners_not_the_images(monkeypatch):
    # View 1 sees the painting shrunk to a quarter in its top-left; an estimate off by a 2 % scale about
    # view 1's origin moves the painting's corners there by at most 0.02 * 64 px, the image's far corner
    # by 6 px: the pair succeeds only if its error is taken at the painting's corners.
    views, masks, homographies = pair(np.diag([0.25, 0.25, 1.0]))
    off = np.diag([1.02, 1.02, 1.0])
    monkeypatch.setattr(matcher, "estimate_homography", lambda points_i, points_j: off @ homographies[0, 1])
    stats = matcher.matcher_stats(views, masks, homographies)
    assert stats.errors[0] < 1.3 and stats.success.tolist() == [True]
    assert matcher.corner_error(off, np.eye(3), matcher.image_corners(SIZE)) > 3


def test_occluder_saturation_is_the_median_over_occluder_pixels_in_the_region():
    view = np.zeros((*SIZE, 3), np.uint8)
    view[:, :] = (200, 100, 50)  # saturation 0.75
    view[:, 100:] = (90, 90, 90)  # grey: saturation 0
    mask = np.zeros(SIZE, bool)
    mask[10:30, 50:100] = True  # 1000 saturated occluder pixels
    mask[10:20, 100:140] = True  # 400 grey ones
    region = np.ones(SIZE, bool)
    assert realism.occluder_saturation(view, mask, region) == pytest.approx(0.75)
    region[:, :90] = False  # 200 saturated pixels left in the region, 400 grey
    assert realism.occluder_saturation(view, mask, region) == 0
    region[:, 100:] = False  # the 200 saturated pixels alone: still at least MIN_OCCLUDER_PIXELS
    assert realism.occluder_saturation(view, mask, region) == pytest.approx(0.75)
    region[:, :98] = False  # 40 pixels: too few
    assert np.isnan(realism.occluder_saturation(view, mask, region))


def test_anchor_homographies_read_every_pair_and_invert_them(tmp_path):
    rng = np.random.default_rng(0)
    for i in range(3):
        for j in range(i + 1, 3):
            np.savetxt(tmp_path / f"H_{i}_{j}.mat", np.eye(3) + 0.01 * rng.standard_normal((3, 3)), fmt="%.18e")
    H = realism.anchor_homographies(tmp_path, 3, SIZE)
    assert np.allclose(H[1, 2], realism.paper_to_kornia(np.loadtxt(tmp_path / "H_1_2.mat"), SIZE))
    assert np.allclose(H[2, 0] @ H[0, 2], np.eye(3)) and np.array_equal(H[1, 1], np.eye(3))
