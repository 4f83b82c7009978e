"""Accuracy: rendered pixels against homographies, homographies against the analytic ones, and the
sampler's coverage and overlap guarantees, each proved on rendered views."""

import kornia
import numpy as np
import pytest
import torch

from sidar_torch import SidarDataset, geometry, load_config
from benchmarks.metrics import homography_errors, speckle_paintings, warp_residuals
from sidar_torch.scene import sample_sequence

pytestmark = pytest.mark.gl  # renders


def ambient_sample(size, index=0, n_views=4, seed=0, **overrides):
    config = load_config("ambient", image_size=size, n_views=n_views, **overrides)
    return SidarDataset(speckle_paintings(index + 1, size, seed), config, seed=seed).sample(index)


def lengths(pairs):
    return np.concatenate([np.linalg.norm(p.displacements, axis=1) for p in pairs])


@pytest.mark.parametrize("size", [(131, 257), (257, 131), (192, 256)])
def test_rendered_views_agree_with_their_homographies_to_a_fraction_of_a_pixel(size):
    found = np.concatenate([lengths(warp_residuals(**pick(ambient_sample(size, index)))) for index in range(2)])
    assert len(found) >= 40
    assert np.median(found) <= 0.05 and found.max() <= 0.2, (np.median(found), found.max())


def pick(sample):
    return {"images": sample["images"], "masks": sample["masks"], "homographies": sample["homographies"]}


def test_the_residual_measurement_sees_a_tenth_of_a_pixel():
    s = ambient_sample((192, 256))
    shifted = s["homographies"].clone()
    shifted[0, 1] = torch.tensor([[1.0, 0, 0.1], [0, 1, -0.05], [0, 0, 1]]) @ shifted[0, 1]
    true, off = (warp_residuals(s["images"], s["masks"], H, pairs=[(0, 1)])[0] for H in (s["homographies"], shifted))
    assert len(off.displacements) >= 10
    # warped(x) = view_j(x + d): moving the warp by (0.1, -0.05) gives d = (-0.1, 0.05).
    assert np.allclose(np.median(off.displacements, axis=0), [-0.1, 0.05], atol=0.015)
    assert np.linalg.norm(np.median(true.displacements, axis=0)) < 0.015
    assert off.photometric_mae > true.photometric_mae


def test_float64_homographies_match_the_analytic_ones_on_random_scenes():
    config = load_config("misaligned")
    errors = [homography_errors(sample_sequence(config, np.random.default_rng([1, i]))) for i in range(100)]
    assert max(e.float64 for e in errors) <= 1e-6
    assert all(e.pairs == 30 for e in errors)  # every view pair shares painting points
    # float32 costs round-off only: well under a thousandth of a pixel here.
    assert 0 < max(e.float32 for e in errors) < 2e-3 and max(e.cycle32 for e in errors) < 2e-3


def visible_fraction(sample, view):
    return float(1 - sample["masks"][view].mean())


@pytest.mark.parametrize("size", [(96, 128), (131, 257)])
def test_painting_pixel_area_matches_the_rendered_mask(size):
    config = load_config("ambient", image_size=size, n_views=5, max_tilt_deg=80, camera_xy=3.0)
    dataset = SidarDataset(speckle_paintings(1, size), config, seed=4)
    for index in range(3):
        s = dataset.sample(index)
        K, R, t = s["K"].double().numpy(), s["R"].double().numpy(), s["t"].double().numpy()
        for v in range(5):
            area = geometry.painting_pixel_area(K[v], R[v], t[v], size) / (size[0] * size[1])
            # Edge pixels are counted whole or not at all by the render: allow the perimeter.
            assert abs(area - visible_fraction(s, v)) <= 2 * (size[0] + size[1]) / (size[0] * size[1]) / 2


def test_sampler_honours_min_coverage_and_min_overlap_on_rendered_views():
    size = (96, 128)
    config = load_config("ambient", image_size=size, n_views=4, min_coverage=0.5, min_overlap=0.75,
                         fov_deg=(60, 110), max_tilt_deg=70, camera_xy=2.0)
    loose = config.replace(min_coverage=0.0, min_overlap=0.0)
    dataset, baseline = (SidarDataset(speckle_paintings(1, size), c, seed=2) for c in (config, loose))
    slack = 2 * sum(size) / (size[0] * size[1])  # edge pixels
    coverages, base_coverages, overlaps = [], [], []
    for index in range(4):
        s, b = dataset.sample(index), baseline.sample(index)
        coverages += [visible_fraction(s, v) for v in range(4)]
        base_coverages += [visible_fraction(b, v) for v in range(4)]
        for i in range(4):
            for j in set(range(4)) - {i}:
                # The painting pixels of view i that view j sees: view j's mask pulled back by H[i, j].
                seen_j = warp_mask(1 - s["masks"][j], s["homographies"][j, i])
                seen_i = 1 - s["masks"][i]
                overlaps.append(float((seen_i * seen_j).sum() / seen_i.sum()))
    assert min(coverages) >= 0.5 - slack
    assert min(overlaps) >= 0.75 - 0.02
    assert min(base_coverages) < 0.5  # without the guarantee the same ranges do go below it


def warp_mask(mask, H):
    h, w = mask.shape[-2:]
    return kornia.geometry.transform.warp_perspective(mask[None], H[None], (h, w), mode="nearest",
                                                      align_corners=True)[0]


def test_impossible_guarantees_raise_instead_of_looping():
    config = load_config("misaligned", min_coverage=0.99, fov_deg=(100, 100.4))
    with pytest.raises(ValueError, match="min_coverage"):
        sample_sequence(config, np.random.default_rng(0))


@pytest.mark.parametrize("overrides", [
    dict(camera_xy=3.0),                              # grazing views (up to 80.5 deg)
    dict(fov_deg=(10, 20)),                           # narrow lenses
    dict(fov_deg=(110, 120)),                         # wide lenses
    dict(camera_height=(0.1, 0.2), max_tilt_deg=60),  # very close
    dict(camera_height=(20, 30), fov_deg=(10, 12)),   # very far
], ids=["grazing", "narrow", "wide", "close", "far"])
def test_hard_views_still_agree_with_their_homographies_when_rendered(overrides):
    found = np.concatenate([lengths(warp_residuals(**pick(ambient_sample((131, 257), index, **overrides))))
                            for index in range(3)])
    assert len(found) >= 5
    assert np.median(found) <= 0.05 and found.max() <= 0.2, (np.median(found), found.max())
