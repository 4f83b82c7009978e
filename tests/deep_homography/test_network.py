"""CornerNet's input normalisation: a light's smooth ramp reaches the encoder less than through a whole-patch
standardisation; the normalisation is named and checked."""

import pytest
import torch

from sidar_torch.deep_homography.network import CornerNet, local_contrast, standardised_grey


def _texture() -> torch.Tensor:
    noise = torch.rand(1, 3, 16, 16, generator=torch.Generator().manual_seed(0))
    return 0.3 + 0.2 * torch.nn.functional.interpolate(noise, (128, 128), mode="bicubic", align_corners=False)


def test_local_contrast_removes_a_lights_ramp_that_standardisation_keeps():
    texture = _texture()
    ramp = torch.linspace(0.0, 0.4, 128).view(1, 1, 1, 128).expand(1, 3, 128, 128)
    lit = (texture * (0.6 + ramp) + 0.5 * ramp).clamp(0, 1)  # a gain and a glow growing across the patch
    change = {f.__name__: float((f(lit) - f(texture)).abs().mean()) for f in (local_contrast, standardised_grey)}
    assert change["local_contrast"] < 0.5 * change["standardised_grey"]


def test_a_flat_patch_comes_out_flat_and_finite():
    out = local_contrast(torch.full((2, 3, 128, 128), 1.0))
    assert out.shape == (2, 1, 64, 64) and torch.isfinite(out).all() and out.abs().max() < 1e-3


def test_an_unknown_normalisation_is_an_error_naming_the_choices():
    with pytest.raises(ValueError, match=r"normalisation: expected one of \['local_contrast', 'standardised'\]"):
        CornerNet(normalisation="none")
