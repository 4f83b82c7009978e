"""Homography math: Kornia's DLT on projected corners against the analytic plane-induced homography."""

import math

import kornia
import numpy as np
import pytest
import torch

from sidar_torch import geometry

SIZE = (384, 512)


def random_cameras(rng, n, size=SIZE):
    """Reference camera plus ``n - 1`` random look-at cameras above the painting."""
    Ks, Rs, ts = zip(geometry.reference_camera(size, rng.uniform(0.7, 1.0)), *[
        (geometry.intrinsics_from_fov(rng.uniform(20, 110), size),
         *geometry.look_at(np.array([*rng.uniform(-0.8, 0.8, 2), rng.uniform(0.3, 3.0)])))
        for _ in range(n - 1)])
    return np.stack(Ks), np.stack(Rs), np.stack(ts)


def test_kornia_dlt_agrees_with_plane_induced_homography(rng):
    worst = 0.0
    for _ in range(40):
        K, R, t = random_cameras(rng, 6)
        corners = geometry.project(K, R, t, geometry.plane_corners(SIZE))
        H_dlt = geometry.homographies_from_points(corners).numpy()
        H_true = geometry.plane_induced_homographies(K, R, t)
        worst = max(worst, geometry.point_disagreement(H_dlt, H_true, corners))
    assert worst < 1e-6
    # The measure sees a small error: one corner of one view moved by 0.01 px.
    moved = corners.copy()
    moved[2, 0, 1] += 0.01
    wrong = geometry.homographies_from_points(moved).numpy()
    assert 0.005 < geometry.point_disagreement(wrong, H_true, corners) < 0.05


def test_a_batch_of_sequences_is_fitted_as_each_alone(rng):
    # SidarAugment fits a batch's homographies in one call: each sequence's, bit for bit.
    for views in (2, 6):
        points = np.stack([geometry.project(*random_cameras(rng, views), geometry.plane_corners(SIZE))
                           for _ in range(8)])
        batched = geometry.homographies_from_points(points)
        assert batched.shape == (8, views, views, 3, 3)
        for alone, fitted in zip(points, batched):
            assert torch.equal(geometry.homographies_from_points(alone), fitted)


def test_homography_identities(rng):
    K, R, t = random_cameras(rng, 5)
    H = geometry.homographies_from_points(geometry.project(K, R, t, geometry.plane_corners(SIZE)))
    eye = torch.eye(3, dtype=torch.float64)
    assert torch.equal(H[torch.arange(5), torch.arange(5)], eye.expand(5, 3, 3))
    assert torch.allclose(H @ H.transpose(0, 1), eye.expand(5, 5, 3, 3), atol=1e-9)
    assert torch.allclose(torch.linalg.det(H), torch.ones(5, 5, dtype=torch.float64), atol=1e-9)


def test_det_normalisation_survives_zero_h22():
    # A valid homography whose H[2, 2] is exactly 0: normalising by it would divide by zero.
    H = torch.tensor([[2.0, 0.5, 10.0], [0.1, 1.5, -3.0], [0.001, 0.002, 0.0]], dtype=torch.float64)
    N = geometry.normalize_det(H)
    assert torch.isfinite(N).all()
    assert math.isclose(torch.linalg.det(N).item(), 1.0, rel_tol=1e-12)
    assert torch.allclose(N / N[0, 0], H / H[0, 0])  # same projective map
    assert torch.allclose(geometry.normalize_det(-H), N)  # the sign of the scale is fixed by det


def test_reference_camera_sees_the_painting_edge_to_edge():
    for size in [(384, 512), (131, 257), (512, 64)]:
        K, R, t = geometry.reference_camera(size, 0.9)
        corners = geometry.project(K, R, t, geometry.plane_corners(size))
        np.testing.assert_allclose(corners, geometry.corner_pixels(size), atol=1e-9)


def test_a_non_finite_fit_raises_naming_kornia(monkeypatch):
    """kornia < 0.9's "lu" DLT gave NaN for some pairs of a batch (0.8.3: a 3-view `ambient` scene's
    H[2, 1]): a NaN homography must never reach a sample."""
    points = np.array([[[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]]] * 2)
    real = kornia.geometry.homography.find_homography_dlt
    monkeypatch.setattr(kornia.geometry.homography, "find_homography_dlt",
                        lambda *args, **kwargs: real(*args, **kwargs) * float("nan"))
    with pytest.raises(RuntimeError, match=r"kornia .* needs kornia >= 0.9"):
        geometry.homographies_from_points(points)


def test_look_at_matches_numpys_cross_bit_for_bit(rng):
    # look_at's cross products (geometry._cross) are np.cross's: the same poses, so the same pixels.
    for scale in (1e-3, 1.0, 1e3):
        for _ in range(2000):
            a, b = rng.normal(size=3) * scale, rng.normal(size=3)
            assert geometry._cross(a, b).tobytes() == np.cross(a, b).tobytes()
    position = np.array([0.3, -0.2, 1.7])
    z = -position / np.linalg.norm(position)
    x = np.cross(z, geometry.WORLD_UP)
    x /= np.linalg.norm(x)
    R, t = geometry.look_at(position)
    assert R.tobytes() == np.stack([x, np.cross(z, x), z]).tobytes() and t.tobytes() == (-R @ position).tobytes()


def test_a_reference_camera_is_recognised_bit_for_bit(rng):
    for _ in range(50):
        size, distance = (int(rng.integers(1, 900)), int(rng.integers(1, 900))), rng.uniform(0.05, 20.0)
        K, R, t = geometry.reference_camera(size, distance)
        assert geometry.is_reference_camera(K, R, t, size)
        nudged = K.copy()
        nudged[0, 0] = np.nextafter(K[0, 0], np.inf)
        assert not geometry.is_reference_camera(nudged, R, t, size)
        assert not geometry.is_reference_camera(K, R, t, (size[0] + 1, size[1]))
    tilted = geometry.look_at(np.array([0.1, 0.0, 1.0]))
    assert not geometry.is_reference_camera(K, *tilted, size)
    assert not geometry.is_reference_camera(K, R, -t, size)  # behind the painting
