"""``SidarAugment``: a batch of the user's images in, SIDAR views + homographies out.

An ``nn.Module`` in the style of ``kornia.augmentation``: each image of a batch becomes the
painting of its own random scene, rendered exactly as :class:`sidar_torch.SidarDataset` renders
a sample (both assemble it with :mod:`sidar_torch.sample`), and the samples come back batched
on the input's device.

>>> aug = SidarAugment("misaligned", n_views=3, image_size=(96, 128), seed=0)
>>> out = aug(torch.rand(4, 3, 120, 160))               # doctest: +SKIP
>>> out["images"].shape, out["homographies"].shape        # doctest: +SKIP
(torch.Size([4, 3, 3, 96, 128]), torch.Size([4, 3, 3, 3, 3]))
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np
import torch
from torch import nn

from .config import SidarConfig, load_config
from .dataset import _check_int
from .sample import render_sample, stack_samples
from .scene import SceneSequence, sample_sequence
from .sources import CROP_MODES, TensorPaintings

__all__ = ["SidarAugment"]

Generator = torch.Generator | np.random.Generator

class SidarAugment(nn.Module):
    """Render every image of a batch as the painting of a random SIDAR scene.

    Args:
        config: a :class:`SidarConfig`, a preset name or a YAML path (default ``"misaligned"``).
        seed: an integer ``>= 0``, or ``None`` to draw from PyTorch's global generator (like
            ``kornia.augmentation``; ``torch.manual_seed`` then makes runs repeatable).
        crop: how images are fitted to ``image_size``, ``"center"`` or ``"none"`` (see below).
        **overrides: config fields replacing the preset's, e.g. ``n_views=3``,
            ``image_size=(h, w)``, ``n_occluders=(0, 1)`` (``load_config(config, **overrides)``).

    Randomness. Image ``b`` of a batch gets its own scene, drawn by ``sample_sequence`` with a
    ``numpy.random.Generator`` that depends only on:

    - with ``seed`` an integer and no ``generator`` passed to :meth:`forward`:
      ``numpy.random.default_rng([seed, call, b])``, where ``call`` counts this module's previous
      such forward calls (attribute ``calls``, starting at 0 and saved in ``state_dict``). Two
      modules with the same seed give the same outputs call after call; successive calls differ;
      a scene never depends on the other images of the batch or on the batch size.
      :meth:`scene` returns the scene of any ``(call, b)`` without rendering.
    - with a ``generator`` passed to :meth:`forward` (a ``torch.Generator`` on any device or a
      ``numpy.random.Generator``): four 32-bit words per image are drawn from it, shape
      ``(B, 4)``, and image ``b`` uses ``numpy.random.default_rng(words[b])``. The outputs are
      then a function of the generator's state (which advances); ``calls`` does not change.
    - with ``seed=None`` and no ``generator``: the words are drawn from PyTorch's global CPU
      generator (``torch.randint``).

    Under DistributedDataParallel give each rank its own seed (e.g. ``seed + rank``), or every
    rank draws the same scenes for its own images.

    Input. :meth:`forward` takes ``images`` ``(B, 3, h, w)``, any floating dtype with values in
    [0, 1], on any device. Images are quantised to 8 bits (``round(x * 255)``, the texture's
    precision) and, if ``(h, w)`` is not ``image_size``, fitted to it exactly as painting sources
    fit images (:class:`sidar_torch.sources.TensorPaintings`, :func:`sidar_torch.sources.fit_painting`:
    the largest centred crop of the output aspect, Lanczos resampling; ``crop="none"`` stretches).
    Rendering runs on the CPU (OSMesa) whatever the input's device, one image after another in
    this process's shared renderer; no gradient flows back to ``images``. For throughput on
    fixed data, :class:`sidar_torch.SidarDataset` in DataLoader workers renders in parallel.

    Output. A dict with the keys of a :class:`sidar_torch.SidarDataset` sample (the table
    :data:`sidar_torch.sample.KEYS`), batched by :func:`sidar_torch.sample.stack_samples`, on the
    input's device: every tensor with a leading ``B`` (``images`` ``(B, V, 3, H, W)``, ...),
    ``homography_error`` ``(B,)`` float32 (not float64 as a DataLoader would collate the dataset's
    floats, so that every device can hold it) and ``index`` ``(B,)`` int64, each image's position
    in the batch.
    """

    def __init__(self, config: SidarConfig | str | os.PathLike | None = "misaligned", *,
                 seed: int | None = None, crop: str = "center", **overrides: Any):
        super().__init__()
        if not isinstance(config, (SidarConfig, str, os.PathLike, type(None))):
            raise TypeError(f"config: expected a SidarConfig, preset name or YAML path, got {type(config).__name__}")
        self.config = load_config(config if config is not None else "misaligned", **overrides)
        self.seed = None if seed is None else _check_int("seed", seed, 0)
        if crop not in CROP_MODES:
            raise ValueError(f"crop: expected one of {CROP_MODES}, got {crop!r}")
        self.crop = crop
        self.calls = 0

    def extra_repr(self) -> str:
        c = self.config
        return f"n_views={c.n_views}, image_size={c.image_size}, seed={self.seed}, crop={self.crop!r}"

    def get_extra_state(self) -> dict[str, int]:
        return {"calls": self.calls}

    def set_extra_state(self, state: dict[str, int]) -> None:
        self.calls = _check_int("calls", state["calls"], 0)

    def scene(self, call: int, position: int) -> SceneSequence:
        """The scene of image ``position`` in forward call number ``call`` (seeded mode only)."""
        if self.seed is None:
            raise ValueError("scene: needs a module built with an integer seed (this one has seed=None)")
        call, position = _check_int("call", call, 0), _check_int("position", position, 0)
        return sample_sequence(self.config, np.random.default_rng([self.seed, call, position]))

    def forward(self, images: torch.Tensor, generator: Generator | None = None) -> dict[str, torch.Tensor]:
        """Render each image of ``images`` ``(B, 3, h, w)`` in its own scene (see the class docstring).

        Args:
            images: float tensor ``(B, 3, h, w)``, values in [0, 1], any device, ``B >= 1``.
            generator: optional ``torch.Generator`` or ``numpy.random.Generator`` to draw the
                scenes from instead of ``(seed, call)``.

        Raises:
            TypeError: ``images`` is not a tensor, or ``generator`` of another type.
            ValueError: wrong shape, dtype, empty batch, NaN/infinite values or values outside [0, 1].
        """
        cpu = _check_images(images)
        paintings = TensorPaintings(cpu, crop=self.crop)
        size = self.config.image_size
        samples = [
            render_sample(sample_sequence(self.config, rng), paintings.painting(b, size), self.config, b, rng=rng)
            for b, rng in enumerate(self._scene_rngs(len(cpu), generator))
        ]
        return {key: value.to(images.device) for key, value in stack_samples(samples).items()}

    def _scene_rngs(self, batch_size: int, generator: Generator | None) -> list[np.random.Generator]:
        if generator is None and self.seed is not None:
            call = self.calls
            self.calls += 1
            return [np.random.default_rng([self.seed, call, b]) for b in range(batch_size)]
        return [np.random.default_rng(words) for words in _draw_words(batch_size, generator)]


def _draw_words(batch_size: int, generator: Generator | None) -> list[list[int]]:
    """``(batch_size, 4)`` integers in ``[0, 2**32)`` from ``generator`` (``None``: torch's global one)."""
    if isinstance(generator, np.random.Generator):
        return generator.integers(0, 2**32, size=(batch_size, 4), dtype=np.uint64).tolist()
    if generator is None or isinstance(generator, torch.Generator):
        device = generator.device if generator is not None else "cpu"
        return torch.randint(0, 2**32, (batch_size, 4), generator=generator, device=device).tolist()
    raise TypeError(f"generator: expected a torch.Generator, a numpy.random.Generator or None, "
                    f"got {type(generator).__name__}")


def _check_images(images: Any) -> torch.Tensor:
    """Validate ``images`` (see :meth:`SidarAugment.forward`) and return a detached CPU copy."""
    if not isinstance(images, torch.Tensor):
        raise TypeError(f"images: expected a torch.Tensor of shape (B, 3, h, w), got {type(images).__name__}")
    shape = tuple(images.shape)
    if images.ndim != 4 or shape[1] != 3 or shape[2] < 1 or shape[3] < 1:
        raise ValueError(f"images: expected shape (B, 3, h, w) with h, w >= 1, got {shape}")
    if shape[0] == 0:
        raise ValueError("images: expected at least one image, got an empty batch (0, 3, h, w)")
    if not images.is_floating_point():
        raise ValueError(f"images: expected a floating-point dtype with values in [0, 1], got {images.dtype}")
    cpu = images.detach().to("cpu", torch.float32)
    if not bool(torch.isfinite(cpu).all()):
        raise ValueError("images: expected finite values in [0, 1], found NaN or infinity")
    low, high = float(cpu.min()), float(cpu.max())
    if low < 0.0 or high > 1.0:
        raise ValueError(f"images: expected values in [0, 1], got range [{low}, {high}]")
    return cpu
