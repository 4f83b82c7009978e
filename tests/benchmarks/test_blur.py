"""The blur measure (``benchmarks/blur.py``) on views whose blur is known."""

import numpy as np
import pytest
from scipy import ndimage

from benchmarks import blur

SIZE = (192, 256)


def painting(seed=0):
    """``(H, W, 3)`` uint8: a textured painting (blobs and sharp steps at every scale)."""
    rng = np.random.default_rng(seed)
    noise = ndimage.gaussian_filter(rng.random((*SIZE, 3)), 1.5)
    steps = (rng.random((SIZE[0] // 8, SIZE[1] // 8, 1)) > 0.5).repeat(8, 0).repeat(8, 1)
    image = 0.15 + 0.5 * steps + 0.35 * (noise - noise.min()) / np.ptp(noise)
    return (255 * image.clip(0, 1)).round().astype(np.uint8)


def lit(view, gain):
    """``view`` ``(H, W, 3)`` uint8 darkened in linear light by ``gain`` ``(H, W)``, re-encoded."""
    return blur.encode(blur.srgb_to_linear(view) * gain[..., None])


@pytest.mark.parametrize("sigma", [0.5, 0.8, 1.0, 1.5])
def test_recovers_a_known_gaussian_blur_under_uneven_light(sigma):
    label = painting()
    y, x = np.mgrid[0:SIZE[0], 0:SIZE[1]] / SIZE[1]
    view = lit(blur.blur_linear(label, sigma), 0.4 + 0.5 * x + 0.2 * y**2)
    mask = np.zeros(SIZE, bool)
    mask[40:90, 60:140] = True  # an occluder: not judged
    view[mask] = 255
    assert blur.view_blur(view, mask, label, np.eye(3)) == pytest.approx(sigma, abs=0.1)


def test_a_sharp_view_measures_below_the_grid_resolution():
    label = painting(1)
    assert blur.view_blur(label, np.zeros(SIZE, bool), label, np.eye(3)) < 0.3


def test_the_homography_is_followed():
    label = painting(2)
    moved = np.array([[1.0, 0, 3], [0, 1, -2], [0, 0, 1]])  # label -> view: 3 px right, 2 up
    view = np.roll(blur.blur_linear(label, 1.0), (-2, 3), axis=(0, 1))
    assert blur.view_blur(view, np.zeros(SIZE, bool), label, moved) == pytest.approx(1.0, abs=0.1)
    assert blur.view_blur(view, np.zeros(SIZE, bool), label, np.eye(3)) > 1.3  # misaligned reads blurrier


def test_too_few_painting_pixels_give_nan_and_wrong_shapes_raise():
    label = painting(3)
    assert np.isnan(blur.view_blur(label, np.ones(SIZE, bool), label, np.eye(3)))
    with pytest.raises(ValueError, match="mask"):
        blur.view_blur(label, np.zeros((10, 10), bool), label, np.eye(3))
