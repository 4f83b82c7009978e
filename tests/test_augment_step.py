"""SidarStep: SidarAugment as one step of a kornia pipeline, with a probability p (issue 34 item 7:
SidarAugment could not sit inside ``kornia.augmentation.AugmentationSequential`` and had no ``p=``)."""

import kornia.augmentation as K
import numpy as np
import pytest
import torch

from sidar_torch import SidarAugment, SidarStep

TINY = (48, 64)


def augment(seed=0, **overrides):
    return SidarAugment("misaligned", seed=seed, **{"image_size": TINY, "n_views": 2, **overrides})


@pytest.mark.gl
def test_inside_augmentation_sequential_each_image_is_its_view_or_left_as_it_is():
    images = torch.rand(6, 3, *TINY)
    step = SidarStep(augment(seed=3), p=0.5)
    pipeline = K.AugmentationSequential(K.RandomHorizontalFlip(p=0.0), step)
    out = pipeline(images)
    applied = step.last["applied"]
    assert out.shape == images.shape and out.dtype == images.dtype
    assert 0 < int(applied.sum()) < 6, applied  # this seed applies to some images, not all
    assert torch.equal(out[~applied], images[~applied])
    # An applied image is view 1 of the sample SidarAugment gives that image, at its position, in that call.
    whole = augment(seed=3)(images)
    positions = applied.nonzero().flatten()
    assert torch.equal(out[applied], whole["images"][positions, 1])
    assert torch.equal(step.last["index"], positions) and torch.equal(step.last["homographies"],
                                                                      whole["homographies"][positions])
    # Reproducible: a fresh step with the same seed draws the same images and scenes; the next call differs.
    again = SidarStep(augment(seed=3), p=0.5)
    assert torch.equal(again(images), out) and torch.equal(again.last["applied"], applied)
    assert step.augment.calls == 1 and not torch.equal(step(images), out)


@pytest.mark.gl
def test_p_one_renders_every_image_at_any_input_size_and_p_zero_none():
    images = (torch.rand(2, 1, 60, 100) * 255).to(torch.uint8)  # grey, another size, uint8
    step = SidarStep(augment(seed=1))
    out = step(images)
    assert out.shape == (2, 3, *TINY) and out.dtype == torch.uint8
    assert torch.equal(out, augment(seed=1)(images)["images"][:, 1])
    none = SidarStep(augment(seed=1), p=0.0)
    left = torch.rand(2, 3, *TINY)
    assert torch.equal(none(left), left) and not none.last["applied"].any() and "images" not in none.last


def test_the_share_of_images_applied_to_is_p_and_a_generator_draws_them():
    step = SidarStep(augment(seed=0), p=0.3)
    drawn = np.concatenate([SidarStep(augment(seed=s), p=0.3)._draw_applied(1000, None) for s in range(10)])
    assert abs(drawn.mean() - 0.3) < 0.02  # 10,000 draws: 5 standard deviations
    first = step._draw_applied(64, torch.Generator().manual_seed(5))
    assert np.array_equal(first, step._draw_applied(64, torch.Generator().manual_seed(5)))
    assert np.array_equal(step._draw_applied(64, np.random.default_rng(2)),
                          step._draw_applied(64, np.random.default_rng(2)))


@pytest.mark.parametrize("kwargs, error, match", [
    ({"view": 2}, ValueError, r"view: expected 0 <= view < n_views = 2, got 2 \(SidarAugment\(..., n_views=3\)"),
    ({"p": 1.5}, ValueError, r"p: expected a probability in \[0, 1\], got 1.5"),
    ({"p": -0.1}, ValueError, r"p: expected a probability in \[0, 1\]"),
])
def test_bad_arguments_are_refused(kwargs, error, match):
    with pytest.raises(error, match=match):
        SidarStep(augment(), **kwargs)


def test_images_the_batch_cannot_hold_are_refused_naming_the_fix():
    with pytest.raises(TypeError, match="augment: expected a SidarAugment"):
        SidarStep(K.ColorJitter())
    step = SidarStep(augment(), p=0.5)
    with pytest.raises(ValueError, match=r"images of \(60, 100\) \(h, w\) with p=0.5: .* build the SidarAugment with "
                                         r"image_size=\(60, 100\)"):
        step(torch.rand(2, 3, 60, 100))
    with pytest.raises(TypeError, match=r"got \(3, 48, 64\); SidarAugment itself takes NumPy images"):
        step(torch.rand(3, *TINY))
    assert step.augment.calls == 0


@pytest.mark.gl
def test_the_module_example_runs():
    import doctest

    import sidar_torch.data.augment_step

    result = doctest.testmod(sidar_torch.data.augment_step, verbose=False)
    assert result.attempted > 0 and result.failed == 0, result
