"""The classic 2-D generator of deep homography training pairs, and ``warps-v1``, a frozen test set of it.

The recipe (DeTone et al. 2016, IHN, and most of their successors): a patch of a photo, its four
corners moved by at most ``rho`` pixels, the photo warped by that homography, the same box of the
warped photo; with a photometric jitter of the second patch, as the unsupervised and Lucas-Kanade
variants add (brightness, contrast, gamma, a gain per channel, Gaussian noise). Written as a
two-view sequence (:func:`classic_sequence`: the painting and a jittered copy of it, the identity
between them), the recipe is the patch protocol of :mod:`.protocol` with nothing but the
perturbation and the jitter between the views, so both kinds of data are cut and scored by one
code path.

``warps-v1`` (:class:`WarpTestSet`) is that sequence for 64 built-in procedural paintings that no
baseline of this package trained on (indices 90000-90063, 384 x 512), each jittered with the
generator ``numpy.random.default_rng([90001, k])``; :data:`WARPS_V1_SHA256` is the digest of its
views as 8-bit levels, which ``evaluate`` checks when it scores the whole set.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from ..paintings import ProceduralPaintings

__all__ = ["JITTER", "WARPS_V1_SHA256", "WarpTestSet", "classic_sequence", "jitter"]

JITTER = {"brightness": (-0.1, 0.1), "contrast": (0.7, 1.3), "gamma": (0.75, 1.33), "gain": (0.9, 1.1),
          "noise": (0.0, 0.02)}
"""Ranges of the photometric jitter, each drawn uniformly: an added brightness, a contrast factor about
0.5, a gamma exponent, a gain per channel, and the standard deviation of Gaussian noise (levels in [0, 1])."""

WARPS_V1_SHA256 = "7cd6e00b9376838c6dc16da67cd35baf9ddf5390be2f352410a4b5ee0d9fc4b2"
"""SHA-256 of ``warps-v1``'s views as 8-bit levels, in sequence order (see :meth:`WarpTestSet.digest`)."""


def jitter(image: torch.Tensor, rng: np.random.Generator) -> torch.Tensor:
    """``image (3, H, W)`` float in [0, 1] with a photometric jitter drawn from :data:`JITTER`, same shape and
    dtype, clipped to [0, 1]. Pointwise except for the noise, so jittering a warped patch or warping
    a jittered view differ only by the interpolation of the noise."""
    brightness, contrast, gamma = (rng.uniform(*JITTER[k]) for k in ("brightness", "contrast", "gamma"))
    gain = torch.as_tensor(rng.uniform(*JITTER["gain"], 3), dtype=image.dtype)[:, None, None]
    noise = torch.as_tensor(rng.normal(0.0, rng.uniform(*JITTER["noise"]), image.shape), dtype=image.dtype)
    out = ((image.clamp(0, 1) ** gamma) * gain - 0.5) * contrast + 0.5 + brightness
    return (out + noise).clamp(0, 1)


def classic_sequence(painting: torch.Tensor, rng: np.random.Generator) -> dict[str, Any]:
    """The 2-D recipe as a two-view sequence: ``images (2, 3, H, W)`` (the painting, a :func:`jitter` of
    it), ``masks (2, 1, H, W)`` zeros, ``homographies (2, 2, 3, 3)`` identities (float64)."""
    images = torch.stack([painting, jitter(painting, rng)])
    _, _, h, w = images.shape
    return dict(images=images, masks=torch.zeros(2, 1, h, w),
                homographies=torch.eye(3, dtype=torch.float64).expand(2, 2, 3, 3).clone())


@dataclass(frozen=True)
class WarpTestSet:
    """``warps-v1``: ``count`` classic sequences (see the module docstring), indexable like an export.

    Attributes:
        count: the number of sequences.
        first: the first procedural painting's index.
        seed: the jitter's seed (sequence ``k`` uses ``default_rng([seed, k])``).
        image_size: ``(H, W)`` pixels.
    """

    count: int = 64
    first: int = 90000
    seed: int = 90001
    image_size: tuple[int, int] = (384, 512)

    def __len__(self) -> int:
        return self.count

    def __getitem__(self, k: int) -> dict[str, Any]:
        if not 0 <= k < self.count:
            raise IndexError(f"warps-v1 has sequences 0..{self.count - 1}, got {k}")
        painting = ProceduralPaintings().painting(self.first + k, self.image_size)
        image = torch.from_numpy(painting).permute(2, 0, 1).float() / 255
        sequence = classic_sequence(image, np.random.default_rng([self.seed, k]))
        sequence["images"] = (sequence["images"] * 255).round() / 255  # 8-bit levels, as an export holds them
        return sequence

    def digest(self) -> str:
        """SHA-256 of every sequence's views as 8-bit levels (row-major ``(2, 3, H, W)`` uint8), in order."""
        sha = hashlib.sha256()
        for k in range(self.count):
            sha.update((self[k]["images"] * 255).round().to(torch.uint8).numpy().tobytes())
        return sha.hexdigest()
