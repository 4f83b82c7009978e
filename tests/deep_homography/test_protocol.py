"""The patch-pair protocol: its truth proved on rendered views, its draws seeded, its arguments checked."""

import numpy as np
import pytest
import torch
import kornia

from sidar_torch import SidarDataset, load_config
from sidar_torch.deep_homography.protocol import PatchPair, cut_pair, draw_pairs, patch_homography, visible_fractions
from sidar_torch.deep_homography.warps import classic_sequence


def _painting(seed: int = 0, size=(96, 128)) -> torch.Tensor:
    """A smooth random RGB image ``(3, H, W)`` in [0, 1] (bilinear interpolation stays accurate on it)."""
    coarse = torch.rand(1, 3, size[0] // 8, size[1] // 8, generator=torch.Generator().manual_seed(seed))
    return torch.nn.functional.interpolate(coarse, size, mode="bicubic", align_corners=False)[0].clamp(0, 1)


def _lands(cut: dict, margin: int = 6, reduce=torch.max) -> float:
    """Largest (or ``reduce``) difference, inside the patch but ``margin`` pixels off its border, between
    the target patch and the source patch warped by the pair's truth."""
    P = cut["source"].shape[-1]
    moved = kornia.geometry.transform.warp_perspective(cut["source"][None].double(), torch.from_numpy(cut["H"])[None],
                                                       (P, P), align_corners=True)[0]
    inner = (slice(None), slice(margin, P - margin), slice(margin, P - margin))
    return float(reduce((moved[inner] - cut["target"][inner].double()).abs()))


def test_truth_moves_source_patch_onto_target_patch_for_a_known_view_homography():
    painting = _painting()
    H_01 = np.array([[1.02, 0.03, 4.0], [-0.02, 0.98, -3.0], [1e-4, -5e-5, 1.0]])
    # view 1 shows the painting moved by H_01: view1(H_01 x) = view0(x)
    view1 = kornia.geometry.transform.warp_perspective(painting[None].double(), torch.from_numpy(H_01)[None],
                                                       (96, 128), align_corners=True)[0].float()
    images = torch.stack([painting, view1])
    pair = PatchPair(0, 0, 1, (40, 30), np.array([[3.0, -2.0], [-4.0, 1.0], [2.5, 3.0], [-1.0, -3.5]]), 48)
    cut = cut_pair(images, H_01, pair)
    assert _lands(cut) < 0.02
    wrong = dict(cut, H=patch_homography(np.zeros((4, 2)), 48))
    assert _lands(wrong) > 0.1  # the check can fail: without the perturbation the patches differ


@pytest.mark.gl
def test_truth_holds_on_rendered_views():
    """Rendered oblique views (ambient light, no occluders): the source patch moved by the truth lands on
    the target patch, which was resampled from another camera's view."""
    config = load_config("ambient", image_size=(192, 256), n_views=3)
    sample = SidarDataset(source=None, config=config, seed=3).sample(1)
    pairs = list(draw_pairs(sample, 1, patch=64, rho=12, min_visible=0.95))
    assert len(pairs) >= 3
    for pair in pairs:
        cut = cut_pair(sample["images"], sample["homographies"][pair.source, pair.target].double().numpy(), pair)
        wrong = dict(cut, H=patch_homography(np.zeros((4, 2)), 64))
        error = _lands(cut, 8, torch.mean)  # 0.006-0.017 measured, the painting's grain resampled
        assert error < 0.025 and error < 0.35 * _lands(wrong, 8, torch.mean), pair


def test_draws_are_seeded_and_differ_between_seeds():
    sequence = classic_sequence(_painting(1, (128, 160)), np.random.default_rng(0))
    first = list(draw_pairs(sequence, 4, seed=7, patch=64, rho=16))
    again = list(draw_pairs(sequence, 4, seed=7, patch=64, rho=16))
    other = list(draw_pairs(sequence, 4, seed=8, patch=64, rho=16))
    assert [(p.source, p.target, p.origin) for p in first] == [(p.source, p.target, p.origin) for p in again]
    assert all(np.array_equal(p.offsets, q.offsets) for p, q in zip(first, again))
    assert [(p.source, p.target) for p in first] == [(0, 1), (1, 0)]
    assert not all(np.array_equal(p.offsets, q.offsets) for p, q in zip(first, other))
    assert all(np.abs(p.offsets).max() <= 16 for p in first)


def test_pairs_without_enough_visible_painting_are_left_out():
    sequence = classic_sequence(_painting(2, (128, 160)), np.random.default_rng(0))
    sequence["masks"][1, :, :, :] = 1  # view 1 shows no painting
    assert list(draw_pairs(sequence, 0, patch=64, rho=16, min_visible=0.5)) == []
    sequence["masks"][1, :, :, 80:] = 0  # its right half does
    pairs = list(draw_pairs(sequence, 0, patch=64, rho=16, min_visible=0.5, attempts=50))
    for pair in pairs:
        seen = visible_fractions(sequence["masks"], np.eye(3), pair)
        assert min(seen) >= 0.5


@pytest.mark.parametrize("argument, value", [("patch", 1), ("patch", 200), ("rho", -1), ("rho", 40),
                                             ("min_visible", 1.5), ("attempts", 0), ("patch", "64")])
def test_bad_arguments_name_themselves(argument, value):
    sequence = classic_sequence(_painting(3, (128, 160)), np.random.default_rng(0))
    arguments = {"patch": 64, "rho": 16, argument: value}
    with pytest.raises(ValueError, match=argument):
        list(draw_pairs(sequence, 0, **arguments))


def test_patch_homography_moves_the_corners_by_the_offsets():
    offsets = np.array([[1.0, 2.0], [-3.0, 0.5], [0.0, -2.0], [4.0, 4.0]])
    Q = patch_homography(offsets, 32)
    corners = np.array([[0, 0, 1], [31, 0, 1], [31, 31, 1], [0, 31, 1]], np.float64)
    moved = corners @ Q.T
    np.testing.assert_allclose(moved[:, :2] / moved[:, 2:] - corners[:, :2], offsets, atol=1e-9)
    assert np.linalg.det(Q) == pytest.approx(1.0)
