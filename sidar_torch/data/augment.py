"""``SidarAugment``: a batch of the user's images in, SIDAR views + homographies out.

An ``nn.Module`` in the style of ``kornia.augmentation``: each image of a batch becomes the
painting of its own random scene, rendered exactly as :class:`sidar_torch.SidarDataset` renders
a sample (both assemble it with :mod:`sidar_torch.sample`), and the samples come back batched
on the input's device.

>>> import torch
>>> from sidar_torch import SidarAugment
>>> aug = SidarAugment("misaligned", n_views=3, image_size=(96, 128), seed=0)
>>> out = aug(torch.rand(4, 3, 120, 160))
>>> out["images"].shape, out["homographies"].shape
(torch.Size([4, 3, 3, 96, 128]), torch.Size([4, 3, 3, 3, 3]))

With ``num_workers=2`` a batch renders in two processes (same outputs, see the class docstring):

>>> images = torch.rand(4, 3, 120, 160)
>>> with SidarAugment("misaligned", n_views=3, image_size=(96, 128), seed=1, num_workers=2) as pooled:
...     alone = SidarAugment("misaligned", n_views=3, image_size=(96, 128), seed=1)
...     torch.equal(pooled(images)["images"], alone(images)["images"])
True
"""

from __future__ import annotations

import os
from typing import Any, Sequence

import numpy as np
import torch
from torch import nn

from .render_pool import RenderPool, RenderTask, render_tasks
from ..config import MAX_WORKERS, SidarConfig, as_float, as_int, load_config
from ..render import RenderSettings, renderer_for
from ..sample import stack_arrays
from ..sample.warm_up import warm_up_renderer
from ..scene import SceneSequence, sample_sequence
from ..paintings import CROP_MODES, array_to_uint8, tensor_to_uint8

__all__ = ["SidarAugment"]

Generator = torch.Generator | np.random.Generator


FLOAT64_FREE_DEVICES = frozenset({"mps"})
"""Device types that hold no float64: ``homography_error`` (float64) arrives there as float32."""

class SidarAugment(nn.Module):
    """Render every image of a batch as the painting of a random SIDAR scene.

    Args:
        config: a :class:`SidarConfig`, a preset name or a YAML path (default ``"misaligned"``).
        seed: an integer ``>= 0``, or ``None`` to draw from PyTorch's global generator (like
            ``kornia.augmentation``; ``torch.manual_seed`` then makes runs repeatable).
        crop: how images are fitted to ``image_size``, ``"center"`` or ``"none"`` (see below).
        num_workers: ``0`` (default): render with this process's renderer (``sidar_torch.render.renderer_for``:
            in a process that may fork, its render process); ``n >= 1``: render each batch in a
            pool of ``n`` render processes (see "Render pool"), at most
            :data:`sidar_torch.config.MAX_WORKERS` (256; each holds its own renderer).
        timeout: with a pool, the most seconds a call may take: sending the images to the workers,
            rendering them and receiving the results (as ``DataLoader``'s ``timeout`` bounds
            fetching a batch); ``0`` (default): no limit, also like ``DataLoader`` (any fixed
            limit would either cut off a legitimately long render of a large batch or be too long
            to help; a worker that dies is noticed at once without one, only a live worker that is
            stopped or deadlocked needs it). A new pool's warm-up is not counted in it (see
            ``warm_up_timeout``). Attribute ``timeout``, read at each call.
        warm_up_timeout: with a pool, the most seconds a new pool's workers may take to warm up
            (compile every shader variant of the config, ``sidar_torch.sample.warm_up``), which they do when
            the pool starts, before the call that starts it sends any image: about 1-2 s each on an
            idle machine (none when this process's renderer was warm at the fork), 48 s was seen on a
            machine at load 15-20. Default 600; ``0``: no limit. Attribute ``warm_up_timeout``.
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

    Input. :meth:`forward` takes ``images`` ``(B, 3, h, w)`` (RGB) or ``(B, 1, h, w)`` (grey,
    copied to the three channels), or one image ``(3, h, w)`` / ``(1, h, w)``, taken as a batch of
    one (``B = 1`` in the output, as ``kornia.augmentation`` does), on any device, either
    ``torch.uint8`` (``0..255``) or any floating dtype with values in [0, 1], the two forms painting
    sources accept (converted by the same function). NumPy images are taken too, channels last as
    OpenCV and albumentations give them (``(B, h, w, 3)``, ``(h, w, 3)``, ``(h, w)``; the output
    is then on the CPU, channels first like every sample). Float images are
    quantised to 8 bits (``round(x * 255)``, the texture's precision) and, if ``(h, w)`` is not
    ``image_size``, fitted to it exactly as painting sources fit images
    (:class:`sidar_torch.paintings.TensorPaintings`, :func:`sidar_torch.paintings.fit_painting`: the
    largest centred crop of the output aspect, Lanczos resampling; ``crop="none"`` stretches).
    Rendering runs on the CPU (OSMesa) whatever the input's device; no gradient flows back to
    ``images``.

    Output. A dict with the keys of a :class:`sidar_torch.SidarDataset` sample (the table
    :data:`sidar_torch.sample.KEYS`), batched as :func:`sidar_torch.sample.stack_samples` batches
    them (by :func:`sidar_torch.sample.stack_arrays`, which converts each key once per batch), on the
    input's device: every tensor with a leading ``B`` (``images`` ``(B, V, 3, H, W)``, ...),
    ``homography_error`` ``(B,)`` float64 (as a DataLoader collates the dataset's Python floats;
    float32 on a device that holds no float64, Apple's MPS) and ``index`` ``(B,)`` int64, each
    image's position in the batch.

    Output dtypes. As in ``kornia.augmentation`` and ``torchvision.transforms.v2``, the pixel keys
    (``images``, ``masks``, ``label``, ``opacities``, ``shadow_masks``, ``shadow_free``:
    :data:`sidar_torch.sample.PIXEL_KEYS`) keep the input's dtype and
    its scale: uint8 in gives uint8 ``0..255`` out (masks ``0`` or ``255``, the values export
    writes), a float dtype in gives that dtype out, in [0, 1] (``k / 255`` for the rendered 8-bit
    value ``k``, exact to that dtype's precision: float32 values equal a dataset sample's). The
    geometry (``homographies``, ``K``, ``R``, ``t``) is in the config's ``geometry_dtype``
    (float32 by default) whatever the input, as in a dataset sample.

    Render pool. With ``num_workers=n`` each forward call splits its batch over ``n`` forked
    processes, each with its own renderer; the pool starts at the first call, is reused by the
    next ones and stops at :meth:`close`, at the end of a ``with`` block, when the module is
    garbage-collected or at interpreter exit; its processes exit by themselves if this one dies.
    Image ``b`` of call ``c`` is drawn and rendered by the same code whichever process renders it
    (which fits the homographies of all the images it renders in one call: a sequence's are the
    same in any batch), so the outputs are ``torch.equal`` whatever ``num_workers`` is. An exception raised in a
    worker is raised again by :meth:`forward`, with the worker's traceback in its notes; a worker
    that dies raises ``RuntimeError`` and the pool restarts at the next call. A pickled or
    deep-copied module (and a module used in another process than the one that started its pool)
    starts its own pool; ``state_dict`` holds ``calls`` only. With ``timeout`` set, a worker that
    does not finish within it (stopped, deadlocked, whether the call is sending it an image,
    waiting for its result or receiving it) raises ``TimeoutError`` naming its pid, its state
    (``stopped``, ``running``...) and what it was doing; the pool is closed (its workers ended,
    nothing left waiting) and the next call starts a new one. A pool pays only
    with idle cores and a warm shader cache, and then less than the number of workers (the
    measured ratio is in ``docs/speed.md``; ``python -m benchmarks.augment_pool``); more workers than
    cores gain nothing.

    When to prefer ``SidarDataset(source=your_images)`` in DataLoader workers instead: when the
    images are a fixed set (a folder, a tensor, a dataset) rather than a batch produced by the
    training loop itself. DataLoader workers render ahead of the training step, overlapping it,
    and spread the decoding and fitting too; ``SidarAugment`` (even with a pool) renders while the
    caller waits, so it suits images that exist only inside the loop (another model's outputs,
    another augmentation's results) or code already written around a ``kornia.augmentation``
    module. Do not combine a pool with DataLoader workers on the same cores: each extra process
    only competes for them.
    """

    def __init__(self, config: SidarConfig | str | os.PathLike | None = "misaligned", *,
                 seed: int | None = None, crop: str = "center", num_workers: int = 0, timeout: float = 0.0,
                 warm_up_timeout: float = 600.0, **overrides: Any):
        super().__init__()
        if not isinstance(config, (SidarConfig, str, os.PathLike, type(None))):
            raise TypeError(f"config: expected a SidarConfig, preset name or YAML path, got {type(config).__name__}")
        self.config = load_config(config if config is not None else "misaligned", **overrides)
        self.seed = None if seed is None else as_int("seed", seed, 0)
        if crop not in CROP_MODES:
            raise ValueError(f"crop: expected one of {CROP_MODES}, got {crop!r}")
        self.crop = crop
        self.num_workers = as_int("num_workers", num_workers, 0, MAX_WORKERS)
        self.timeout, self.warm_up_timeout = (_seconds(name, value) for name, value in
                                              (("timeout", timeout), ("warm_up_timeout", warm_up_timeout)))
        self.calls = 0
        self._pool: RenderPool | None = None

    def extra_repr(self) -> str:
        c = self.config
        return (f"n_views={c.n_views}, image_size={c.image_size}, seed={self.seed}, crop={self.crop!r}, "
                f"num_workers={self.num_workers}, timeout={self.timeout}, warm_up_timeout={self.warm_up_timeout}")

    def get_extra_state(self) -> dict[str, int]:
        return {"calls": self.calls}

    def set_extra_state(self, state: dict[str, int]) -> None:
        self.calls = as_int("calls", state["calls"], 0)

    def __getstate__(self) -> dict[str, Any]:
        """Pickled (and deep-copied) state: everything but the render pool, which a copy starts anew."""
        return {**self.__dict__, "_pool": None}

    def close(self) -> None:
        """Stop the render pool, if one is running (safe to call twice; the next call starts a new one)."""
        if self._pool is not None:
            self._pool.close()
            self._pool = None

    def __enter__(self) -> "SidarAugment":
        return self

    def __exit__(self, *exc_info: Any) -> None:
        self.close()

    def scene(self, call: int, position: int) -> SceneSequence:
        """The scene of image ``position`` in forward call number ``call`` (seeded mode only)."""
        if self.seed is None:
            raise ValueError("scene: needs a module built with an integer seed (this one has seed=None)")
        call, position = as_int("call", call, 0), as_int("position", position, 0)
        return sample_sequence(self.config, np.random.default_rng([self.seed, call, position]))

    def forward(self, images: torch.Tensor, generator: Generator | None = None) -> dict[str, torch.Tensor]:
        """Render each image of ``images`` in its own scene (see the class docstring).

        Args:
            images: ``(B, 3, h, w)`` or ``(B, 1, h, w)`` (or one image ``(3, h, w)``, ``(1, h, w)``:
                ``B = 1``), uint8 or float in [0, 1], any device, ``B >= 1``; or a NumPy array,
                channels last as OpenCV and albumentations give them: ``(B, h, w, 3)``, ``(h, w, 3)``,
                ``(h, w)`` (the output is then on the CPU, pixel keys in the array's dtype).
            generator: optional ``torch.Generator`` or ``numpy.random.Generator`` to draw the
                scenes from instead of ``(seed, call)``.

        Returns:
            The batched sample dict; pixel keys in ``images.dtype`` (see "Output dtypes").

        Raises:
            TypeError: ``images`` is not a tensor or NumPy array, or ``generator`` of another type.
            ValueError: wrong shape or dtype, empty batch, NaN/infinite values or float values outside [0, 1].
        """
        pixels, dtype, device = _check_images(images)
        return self._augment(pixels, self._scene_entropy(len(pixels), generator), range(len(pixels)), dtype, device)

    def _augment(self, pixels: np.ndarray, entropy: Sequence[list[int]], positions: Sequence[int],
                 dtype: torch.dtype, device: torch.device) -> dict[str, torch.Tensor]:
        """Render ``pixels[k]`` (``(K, 3, h, w)`` uint8) as image ``positions[k]`` of the batch, its scene
        drawn with ``entropy[k]``; the batched sample dict, pixel keys in ``dtype``, on ``device``."""
        tasks: list[RenderTask] = [(int(b), e, image) for b, e, image in zip(positions, entropy, pixels)]
        batch = stack_arrays(self._render(tasks), self.config.geometry_dtype, pixel_dtype=dtype)
        return {key: _to_device(value, key, device) for key, value in batch.items()}

    def _render(self, tasks: list[RenderTask]):
        if self.num_workers == 0:  # this process's renderer, warm before its first batch (as a pool's workers)
            renderer = renderer_for(RenderSettings.from_config(self.config))
            warm_up_renderer(renderer, self.config)
            return render_tasks(renderer, self.config, self.crop, tasks)
        if self._pool is None or not self._pool.usable:
            self._pool = RenderPool(self.config, self.crop, self.num_workers, self.warm_up_timeout)
        return self._pool.run(tasks, self.timeout)

    def _scene_entropy(self, batch_size: int, generator: Generator | None) -> list[list[int]]:
        """Per image, the entropy of its generator (``numpy.random.default_rng(entropy)``)."""
        if generator is None and self.seed is not None:
            call = self.calls
            self.calls += 1
            return [[self.seed, call, b] for b in range(batch_size)]
        return _draw_words(batch_size, generator)


def _seconds(name: str, value: Any) -> float:
    """``value`` as seconds ``>= 0`` (``0``: no limit).

    Raises:
        ValueError: not a finite number ``>= 0`` (the message names ``name``).
    """
    seconds = as_float(name, value)
    if seconds < 0:
        raise ValueError(f"{name}: expected seconds >= 0 (0: no limit), got {value!r}")
    return seconds


def _draw_words(batch_size: int, generator: Generator | None) -> list[list[int]]:
    """``(batch_size, 4)`` integers in ``[0, 2**32)`` from ``generator`` (``None``: torch's global one)."""
    if isinstance(generator, np.random.Generator):
        return generator.integers(0, 2**32, size=(batch_size, 4), dtype=np.uint64).tolist()
    if generator is None or isinstance(generator, torch.Generator):
        device = generator.device if generator is not None else "cpu"
        return torch.randint(0, 2**32, (batch_size, 4), generator=generator, device=device).tolist()
    raise TypeError(f"generator: expected a torch.Generator, a numpy.random.Generator or None, "
                    f"got {type(generator).__name__}")


def _to_device(values: Any, key: str, device: torch.device) -> Any:
    """``values`` on ``device`` when a tensor (anything else, e.g. the ``lens_model`` names, as it is);
    ``homography_error`` as float32 on a device that holds no float64."""
    if not isinstance(values, torch.Tensor):
        return values
    if key == "homography_error" and device.type in FLOAT64_FREE_DEVICES:
        values = values.float()
    return values.to(device)


def _check_images(images: Any) -> tuple[np.ndarray, torch.dtype, torch.device]:
    """Validate ``images`` (see :meth:`SidarAugment.forward`): their pixels as ``(B, 3, h, w)`` uint8
    NumPy (float values ``round(x * 255)``, grey copied to three channels, with the conversion
    painting sources use: :func:`sidar_torch.paintings.tensor_to_uint8`, ``array_to_uint8``), and the
    dtype and device of the output's pixel keys (a NumPy array's own dtype, on the CPU)."""
    if isinstance(images, np.ndarray):
        pixels = array_to_uint8(images, batched=True, name="images").numpy()
        return pixels, torch.from_numpy(np.empty(0, images.dtype.newbyteorder("="))).dtype, torch.device("cpu")
    if not isinstance(images, torch.Tensor):
        raise TypeError(f"images: expected a torch.Tensor of shape (B, 3, h, w) or (B, 1, h, w), or a NumPy array "
                        f"(B, h, w, 3) or (h, w, 3), got {type(images).__name__}")
    return tensor_to_uint8(images, batched=True, name="images", grey=True).numpy(), images.dtype, images.device
