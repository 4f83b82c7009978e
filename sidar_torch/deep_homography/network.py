"""A compact correlation network for the four-corner homography of two patches (the ``sidar-net`` and
``warp-net`` baselines share it).

Why this design: a plain HomographyNet (DeTone et al. 2016) regresses corners from stacked images
and needs millions of pairs; on a 2-core CPU budget of tens of thousands of pairs it barely beats
the identity. Matching is easier to learn from a cost volume, as IHN (Cao et al. 2022) and RAFT do:

1. both patches (``(N, 3, 128, 128)`` RGB in [0, 1]) become grey, are area-resized to 64 x 64 and
   locally contrast-normalised (:func:`local_contrast`: minus the Gaussian-weighted mean of a
   neighbourhood, over its standard deviation), so that the smooth brightness ramps of spot lights,
   shadows and highlights and any change of brightness or contrast reach the net as little as they
   can (a whole-patch standardisation, the first version's, leaves a light's ramp in);
2. one shared encoder (five 3 x 3 conv-BN-ReLU layers, two of stride 2) maps each to ``(N, 64, 16,
   16)`` features, one cell per 8 x 8 pixels of the 128 patch;
3. ``ITERATIONS`` rounds: the target's features are warped by the current estimate, the local
   correlation of the two feature maps within ``RADIUS`` cells (``(2 RADIUS + 1)^2`` channels, each a
   dot product over channels divided by sqrt(64)) goes through a small CNN that predicts a
   correction of the four corners' offsets; the rounds share their weights (IHN's iterations).

The output is the four corners' offsets (TL, TR, BR, BL; du, dv) in pixels of the 128 patch, from
which :func:`sidar_torch.deep_homography.protocol.patch_homography` makes ``H``. About 0.5 M
parameters (2 MB as float32).
"""

from __future__ import annotations

import kornia
import torch
from torch import nn
from torch.nn import functional as F

__all__ = ["CornerNet", "ITERATIONS", "NORMALISATIONS", "RADIUS", "local_contrast", "standardised_grey"]

RADIUS = 4
"""Correlation reach, feature cells (8 patch pixels each): 4 cells cover a 32 px perturbation."""

ITERATIONS = 3
"""Refinement rounds, each a correlation of the target warped by the estimate so far."""

INPUT = 64
"""Side (pixels) the patches are area-resized to before the encoder."""

SCALE = 32.0
"""Offsets are predicted in units of this many patch pixels (the default perturbation)."""


def _block(inputs: int, outputs: int, stride: int = 1) -> list[nn.Module]:
    return [nn.Conv2d(inputs, outputs, 3, stride, 1, bias=False), nn.BatchNorm2d(outputs), nn.ReLU(inplace=True)]


SIGMA = 4.0
"""Standard deviation (input pixels, 2 patch pixels each at 128 px) of the Gaussian neighbourhood of
:func:`local_contrast`."""

EPSILON = 0.02
"""Added to the local standard deviation (grey levels in [0, 1]): flat areas (a blown-out highlight, a black
pool) come out near 0 instead of as amplified noise."""


def standardised_grey(patches: torch.Tensor, size: int = INPUT) -> torch.Tensor:
    """``(N, 3, P, P)`` RGB in [0, 1] -> ``(N, 1, size, size)`` grey, area-resized, mean 0 and std 1 each (the
    first version's input, that of weights recorded with ``"normalisation": "standardised"``)."""
    grey = kornia.color.rgb_to_grayscale(patches.float())
    grey = F.interpolate(grey, (size, size), mode="area") if grey.shape[-1] != size else grey
    mean, std = grey.mean((2, 3), keepdim=True), grey.std((2, 3), keepdim=True)
    return (grey - mean) / (std + 1e-3)


def local_contrast(patches: torch.Tensor, size: int = INPUT) -> torch.Tensor:
    """``(N, 3, P, P)`` RGB in [0, 1] -> ``(N, 1, size, size)``: grey, area-resized to ``size``, minus its
    local mean, over its local standard deviation plus :data:`EPSILON` (both Gaussian-weighted,
    :data:`SIGMA`, reflected at the border)."""
    grey = kornia.color.rgb_to_grayscale(patches.float())
    grey = F.interpolate(grey, (size, size), mode="area") if grey.shape[-1] != size else grey
    kernel, sigma = 2 * int(3 * SIGMA) + 1, (SIGMA, SIGMA)
    detail = grey - kornia.filters.gaussian_blur2d(grey, (kernel, kernel), sigma, border_type="reflect")
    spread = kornia.filters.gaussian_blur2d(detail * detail, (kernel, kernel), sigma, border_type="reflect")
    return detail / (spread.clamp_min(0).sqrt() + EPSILON)


NORMALISATIONS = {"local_contrast": local_contrast, "standardised": standardised_grey}
"""What :class:`CornerNet` can feed its encoder: ``local_contrast`` (the default, what the networks are trained
with) or ``standardised`` (the first shipped weights' input)."""


class CornerNet(nn.Module):
    """Source and target patches ``(N, 3, P, P)`` -> ``(ITERATIONS, N, 4, 2)`` float32: the corners'
    offsets in patch pixels after each round (the last is the estimate; the others feed the training
    loss). ``patch`` is ``P``; patches are resized to ``min(P, INPUT)`` pixels, a multiple of 4."""

    def __init__(self, patch: int = 128, features: int = 64, radius: int = RADIUS, iterations: int = ITERATIONS,
                 normalisation: str = "local_contrast"):
        super().__init__()
        if normalisation not in NORMALISATIONS:
            raise ValueError(f"normalisation: expected one of {sorted(NORMALISATIONS)}, got {normalisation!r}")
        self.normalisation, self._normalise = normalisation, NORMALISATIONS[normalisation]
        self.patch, self.radius, self.iterations = patch, radius, iterations
        self.input = min(patch, INPUT)
        if self.input % 4:
            raise ValueError(f"patch: expected at least {INPUT} or a multiple of 4, got {patch}")
        self.encoder = nn.Sequential(*_block(1, 32), *_block(32, 32, 2), *_block(32, 48), *_block(48, features, 2),
                                     nn.Conv2d(features, features, 3, 1, 1))
        channels = (2 * radius + 1) ** 2
        self.update = nn.Sequential(*_block(channels, 96), nn.MaxPool2d(2), *_block(96, 128), nn.MaxPool2d(2),
                                    *_block(128, 128), nn.AdaptiveAvgPool2d(2), nn.Flatten(),
                                    nn.Linear(512, 256), nn.ReLU(inplace=True), nn.Linear(256, 8))
        nn.init.zeros_(self.update[-1].weight)
        nn.init.zeros_(self.update[-1].bias)

    def forward(self, source: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        a = self.encoder(self._normalise(source, self.input))
        b = self.encoder(self._normalise(target, self.input))
        n, _, h, w = a.shape
        cell = self.patch / w  # patch pixels per feature cell
        # Feature-cell centres in patch pixels: cell (x, y) covers pixels [x cell, (x + 1) cell).
        side = torch.tensor([[0.0, 0.0], [w - 1.0, 0.0], [w - 1.0, h - 1.0], [0.0, h - 1.0]], device=a.device)
        corners = side.expand(n, 4, 2)
        offsets = torch.zeros(n, 4, 2, device=a.device)
        estimates = []
        for _ in range(self.iterations):
            # target features at the estimate: warped(x) = b(H x), H the corners' motion in cells
            H_cells = kornia.geometry.transform.get_perspective_transform(corners, corners + offsets / cell)
            warped = kornia.geometry.transform.warp_perspective(b, torch.linalg.inv(H_cells), (h, w),
                                                                align_corners=True)
            offsets = offsets + self.update(self._correlation(a, warped)).view(n, 4, 2) * SCALE
            estimates.append(offsets)
        return torch.stack(estimates)

    def _correlation(self, a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
        """``(N, (2r + 1)^2, h, w)``: ``a``'s feature at each cell dotted with ``b``'s at every shift
        within ``r`` cells (zero padding), over sqrt(channels)."""
        r = self.radius
        n, c, h, w = a.shape
        padded = F.pad(b, (r, r, r, r))
        shifted = [padded[:, :, dy:dy + h, dx:dx + w] for dy in range(2 * r + 1) for dx in range(2 * r + 1)]
        return torch.stack([(a * s).sum(1) for s in shifted], 1) / c ** 0.5
