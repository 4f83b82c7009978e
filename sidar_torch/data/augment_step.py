"""``SidarStep``: :class:`~sidar_torch.SidarAugment` as one image -> image step of an augmentation
pipeline, applied to each image with probability ``p``, as ``kornia.augmentation`` steps are.

``SidarAugment`` hands out a whole sample per image (``V`` views, masks, label, homographies...);
a pipeline step such as a member of ``kornia.augmentation.AugmentationSequential`` or of
``torchvision.transforms.v2.Compose`` takes a batch ``(B, C, h, w)`` and hands out one. The step
gives, for each image it applies to, view ``view`` of that image's SIDAR sample, and keeps the
whole sample in :attr:`SidarStep.last` (its homographies map the input's frame, fitted to
``image_size``, to the view: view 0 is the fronto-parallel reference).

>>> import torch, kornia.augmentation as K
>>> from sidar_torch import SidarAugment, SidarStep
>>> step = SidarStep(SidarAugment("misaligned", seed=0, n_views=2, image_size=(48, 64)), p=0.5)
>>> pipeline = K.AugmentationSequential(K.ColorJitter(0.1, 0.1, p=1.0), step)
>>> pipeline(torch.rand(4, 3, 48, 64)).shape
torch.Size([4, 3, 48, 64])
>>> step.last["applied"].shape, step.last["images"].shape[1:]  # which images, and their samples
(torch.Size([4]), torch.Size([2, 3, 48, 64]))
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch
from torch import nn

from .augment import Generator, SidarAugment, _check_images
from ..config import as_float, as_int

__all__ = ["SidarStep"]

APPLY_STREAM = 1
"""``spawn_key`` of the seeded draws that pick the images a call applies to:
``numpy.random.SeedSequence([seed, call], spawn_key=(APPLY_STREAM,))``, a stream of its own beside the
scenes' ``[seed, call, b]``."""


class SidarStep(nn.Module):
    """Replace each image of a batch, with probability ``p``, by a view of its own SIDAR sample.

    Args:
        augment: the :class:`~sidar_torch.SidarAugment` that renders (its config, seed, pool, timeout).
            Give it ``n_views=2`` when the step is all you use: view 0 is the reference camera,
            view 1 a distorted one.
        view: which view to hand out, ``0 <= view < n_views`` (default 1).
        p: the probability that an image is replaced (default 1), as in ``kornia.augmentation``.

    :meth:`forward` takes ``images`` ``(B, 3, h, w)`` or ``(B, 1, h, w)``, uint8 or float in [0, 1], on
    any device, and returns ``(B, 3, H, W)`` in their dtype and on their device: image ``b`` is view
    ``view`` of its sample if it is applied to, else left as it is (grey copied to three channels).
    With ``p < 1`` the images must already be ``image_size`` (``(H, W) = (h, w)``), so that both kinds
    fit one batch; with ``p = 1`` any size is fitted as ``SidarAugment`` fits it.

    Which images are applied to is drawn reproducibly, each with probability ``p``: with the
    augment's integer ``seed`` and no generator, from ``SeedSequence([seed, call], spawn_key=(1,))``
    (``call``: the augment's ``calls`` before the call, which every call advances by one, however
    many images it applies to); with a ``generator`` (``torch.Generator`` or
    ``numpy.random.Generator``), from it, before the scenes' words; with ``seed=None``, from PyTorch's
    global generator. Image ``b`` of call ``c`` gets the same scene as ``SidarAugment`` gives it
    (``[seed, c, b]`` when seeded), whichever other images are applied to.

    Attributes:
        last: after a call, the sample dict of the images applied to (``SidarAugment``'s keys, batched
            over them in order; ``index`` holds their positions in the batch, ``homographies`` map
            their fitted input to each view) and ``"applied"``, ``(B,)`` bool; ``None`` before.

    Inside ``kornia.augmentation.AugmentationSequential`` the step is a plain module: kornia applies
    it to the images only, not to masks, boxes or keypoints passed beside them (map those with
    ``last["homographies"][:, 0, view]``), and ``inverse`` cannot undo it.
    """

    def __init__(self, augment: SidarAugment, *, view: int = 1, p: float = 1.0):
        super().__init__()
        if not isinstance(augment, SidarAugment):
            raise TypeError(f"augment: expected a SidarAugment, got {type(augment).__name__}")
        self.augment = augment
        n_views = augment.config.n_views
        self.view = as_int("view", view, 0)
        if self.view >= n_views:
            raise ValueError(f"view: expected 0 <= view < n_views = {n_views}, got {view} (SidarAugment(..., "
                             f"n_views={self.view + 1}) renders it)")
        self.p = as_float("p", p)
        if not 0.0 <= self.p <= 1.0:
            raise ValueError(f"p: expected a probability in [0, 1], got {p!r}")
        self.last: dict[str, torch.Tensor] | None = None

    def extra_repr(self) -> str:
        return f"view={self.view}, p={self.p}"

    def forward(self, images: torch.Tensor, generator: Generator | None = None) -> torch.Tensor:
        """Apply the step (see the class docstring).

        Args:
            images: ``(B, 3, h, w)`` or ``(B, 1, h, w)``, uint8 or float in [0, 1], ``B >= 1``.
            generator: optional ``torch.Generator`` or ``numpy.random.Generator`` drawing which
                images are applied to and their scenes.

        Returns:
            ``(B, 3, H, W)``, ``images.dtype``, on ``images.device``.

        Raises:
            TypeError: ``images`` is not a tensor, or ``generator`` of another type.
            ValueError: what ``SidarAugment`` refuses; ``p < 1`` with images of another size than
                ``image_size`` (the message says how to build the augment).
        """
        if not isinstance(images, torch.Tensor) or images.ndim != 4:
            raise TypeError(f"images: expected a torch.Tensor (B, 3, h, w) or (B, 1, h, w), got "
                            f"{tuple(images.shape) if isinstance(images, torch.Tensor) else type(images).__name__}"
                            "; SidarAugment itself takes NumPy images and single images")
        size = tuple(self.augment.config.image_size)
        if self.p < 1.0 and tuple(images.shape[-2:]) != size:
            raise ValueError(f"images of {tuple(images.shape[-2:])} (h, w) with p={self.p}: the images left as they "
                             f"are must have the config's image_size {size} to share the batch; build the "
                             f"SidarAugment with image_size={tuple(images.shape[-2:])}")
        pixels, dtype, device = _check_images(images)
        applied = self._draw_applied(len(pixels), generator)
        entropy = self.augment._scene_entropy(len(pixels), generator)
        positions = np.flatnonzero(applied)
        out = images.expand(-1, 3, -1, -1).clone() if self.p < 1.0 else None
        sample: dict[str, Any] = {}
        if len(positions):
            sample = self.augment._augment(pixels[positions], [entropy[b] for b in positions], positions, dtype, device)
            views = sample["images"][:, self.view]
            out = views if out is None else out.index_put_((torch.from_numpy(positions).to(device),), views)
        self.last = {**sample, "applied": torch.from_numpy(applied)}
        return out

    def _draw_applied(self, batch_size: int, generator: Generator | None) -> np.ndarray:
        """``(batch_size,)`` bool: which images this call applies to (see the class docstring)."""
        if self.p == 1.0:
            return np.ones(batch_size, bool)
        if generator is None and self.augment.seed is not None:
            entropy = np.random.SeedSequence([self.augment.seed, self.augment.calls], spawn_key=(APPLY_STREAM,))
            uniform = np.random.default_rng(entropy).random(batch_size)
        elif isinstance(generator, np.random.Generator):
            uniform = generator.random(batch_size)
        elif generator is None or isinstance(generator, torch.Generator):
            device = generator.device if generator is not None else "cpu"
            uniform = torch.rand(batch_size, generator=generator, device=device, dtype=torch.float64).cpu().numpy()
        else:
            raise TypeError(f"generator: expected a torch.Generator, a numpy.random.Generator or None, "
                            f"got {type(generator).__name__}")
        return uniform < self.p
