"""Training pairs and the training loop of the ``sidar-net`` and ``warp-net`` baselines.

Both data arms cut pairs with :mod:`.protocol` (one code path), and a batch is a pure function of
``(seed, step)``, so a run stopped at any step resumes to the same weights:

- :class:`SidarPairs`: rendered sequences (views, masks, homographies) held in memory as 8-bit
  levels; a pair is a random sequence, a random ordered view pair and the protocol's draw on it.
- :class:`WarpPairs`: the classic 2-D recipe on the same paintings (:mod:`.warps`): a random box
  and perturbation of a painting, the target patch jittered.

:func:`train` runs AdamW with a one-cycle learning rate on the L1 error of the corners' offsets
after every refinement round (later rounds weighted more, as IHN does), and writes a checkpoint
(weights, optimiser, schedule, step) every ``checkpoint_every`` steps when given a path.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Callable, Protocol

import numpy as np
import torch
from torch import nn

from ..config import as_int
from .network import CornerNet
from .network import NORMALISATIONS
from .protocol import PATCH, RHO, PatchPair, cut_pair, draw_pair, draw_pairs
from .warps import jitter

__all__ = ["PairSource", "SidarPairs", "TrainSettings", "WarpPairs", "corner_loss", "protocol_errors", "train"]

Batch = tuple[torch.Tensor, torch.Tensor, torch.Tensor]
"""``(source, target, offsets)``: patches ``(N, 3, P, P)`` float32 in [0, 1], the truth's corner offsets
``(N, 4, 2)`` float32 pixels."""


class PairSource(Protocol):
    """Anything that cuts a batch of pairs of ``patch x patch`` pixels from a NumPy generator."""

    patch: int

    def batch(self, rng: np.random.Generator, size: int) -> Batch: ...


def _levels(array: np.ndarray | torch.Tensor) -> torch.Tensor:
    return torch.as_tensor(array).float() / 255


class SidarPairs:
    """Protocol pairs from rendered sequences.

    Args:
        images: ``(S, V, 3, H, W)`` uint8 views.
        masks: ``(S, V, 1, H, W)`` uint8 in {0, 1} (1: painting not visible).
        homographies: ``(S, V, V, 3, 3)`` float64.
        patch, rho, min_visible: as in :func:`sidar_torch.deep_homography.protocol.draw_pairs`.
    """

    def __init__(self, images: torch.Tensor, masks: torch.Tensor, homographies: torch.Tensor, patch: int = PATCH,
                 rho: float = RHO, min_visible: float = 0.5):
        self.images, self.masks, self.homographies = images, masks, homographies
        self.patch, self.rho, self.min_visible = patch, rho, min_visible

    def batch(self, rng: np.random.Generator, size: int) -> Batch:
        sources, targets, offsets = [], [], []
        S, V = self.images.shape[:2]
        while len(sources) < size:
            k, i = int(rng.integers(S)), int(rng.integers(V))
            j = (i + 1 + int(rng.integers(V - 1))) % V
            views = [i, j]
            sample = dict(images=_levels(self.images[k, views]), masks=self.masks[k, views].float(),
                          homographies=self.homographies[k][views][:, views])
            pair = draw_pair(sample, k, 0, 1, rng, self.patch, self.rho, self.min_visible, attempts=4)
            if pair is not None:
                cut = cut_pair(sample["images"], sample["homographies"][0, 1].numpy(), pair)
                sources.append(cut["source"])
                targets.append(cut["target"])
                offsets.append(torch.from_numpy(pair.offsets).float())
        return torch.stack(sources), torch.stack(targets), torch.stack(offsets)


class WarpPairs:
    """Classic 2-D pairs (:mod:`.warps`) from paintings ``(S, 3, H, W)`` uint8: the protocol on a painting
    and itself (identity), the target patch jittered (:func:`sidar_torch.deep_homography.warps.jitter`)."""

    def __init__(self, paintings: torch.Tensor, patch: int = PATCH, rho: float = RHO):
        self.paintings, self.patch, self.rho = paintings, patch, rho

    def batch(self, rng: np.random.Generator, size: int) -> Batch:
        sources, targets, offsets = [], [], []
        S, _, H, W = self.paintings.shape
        margin = int(np.ceil(self.rho))
        for _ in range(size):
            image = _levels(self.paintings[int(rng.integers(S))])[None]
            origin = (int(rng.integers(margin, W - self.patch - margin + 1)),
                      int(rng.integers(margin, H - self.patch - margin + 1)))
            pair = PatchPair(0, 0, 0, origin, rng.uniform(-self.rho, self.rho, (4, 2)), self.patch)
            cut = cut_pair(image, np.eye(3), pair)
            sources.append(cut["source"])
            targets.append(jitter(cut["target"], rng))
            offsets.append(torch.from_numpy(pair.offsets).float())
        return torch.stack(sources), torch.stack(targets), torch.stack(offsets)


@torch.no_grad()
def protocol_errors(network: nn.Module | None, sequences, patch: int = PATCH, rho: float = RHO) -> np.ndarray:
    """Corner errors (pixels, the mean of the four corners' distances) of ``network`` (``None``: the
    identity) on the protocol's pairs (seed 0) of ``sequences``, an indexable of dicts with ``images``
    ``(V, 3, H, W)`` (uint8, or float in [0, 1]), ``masks`` ``(V, 1, H, W)`` and ``homographies``."""
    errors = []
    for k in range(len(sequences)):
        sample = sequences[k]
        images = _levels(sample["images"]) if sample["images"].dtype == torch.uint8 else sample["images"]
        sample = dict(sample, images=images, masks=sample["masks"].float())
        for pair in draw_pairs(sample, k, patch=patch, rho=rho):
            cut = cut_pair(images, sample["homographies"][pair.source, pair.target].double().numpy(), pair)
            truth = torch.from_numpy(pair.offsets).float()
            estimate = torch.zeros(4, 2) if network is None else network(cut["source"][None], cut["target"][None])[-1, 0]
            errors.append(float((estimate - truth).norm(dim=-1).mean()))
    return np.array(errors)


def corner_loss(estimates: torch.Tensor, offsets: torch.Tensor, decay: float = 0.85) -> torch.Tensor:
    """IHN's sequence loss: ``sum_k decay^(K-1-k) mean |estimates[k] - offsets|`` over the rounds
    ``estimates (K, N, 4, 2)`` against ``offsets (N, 4, 2)``, pixels."""
    K = len(estimates)
    weights = decay ** torch.arange(K - 1, -1, -1, dtype=estimates.dtype)
    return (weights * (estimates - offsets).abs().mean((1, 2, 3))).sum()


class TrainSettings:
    """The budget and optimiser of a run, the same for both arms: ``steps`` (at least 3, what the one-cycle
    schedule needs for a rise and a fall), pairs per step ``batch``, AdamW's peak ``lr`` and ``weight_decay``,
    the ``seed`` of the weights and of every batch, how often a checkpoint is written and progress reported, and
    the network's input ``normalisation`` (:data:`sidar_torch.deep_homography.network.NORMALISATIONS`)."""

    def __init__(self, steps: int = 1500, batch: int = 32, lr: float = 1e-3, weight_decay: float = 1e-4,
                 seed: int = 0, checkpoint_every: int = 100, normalisation: str = "local_contrast"):
        steps, batch = as_int("steps", steps, 3), as_int("batch", batch, 1)
        checkpoint_every, seed = as_int("checkpoint_every", checkpoint_every, 1), as_int("seed", seed, 0)
        self.steps, self.batch, self.lr, self.weight_decay = steps, batch, lr, weight_decay
        self.seed, self.checkpoint_every = seed, checkpoint_every
        if normalisation not in NORMALISATIONS:
            raise ValueError(f"normalisation: expected one of {sorted(NORMALISATIONS)}, got {normalisation!r}")
        self.normalisation = normalisation

    def __repr__(self) -> str:
        return (f"TrainSettings(steps={self.steps}, batch={self.batch}, lr={self.lr}, weight_decay={self.weight_decay}, "
                f"seed={self.seed}, normalisation={self.normalisation!r})")


def train(pairs: PairSource, settings: TrainSettings, checkpoint: Path | None = None,
          report: Callable[[int, float, float], None] | None = None) -> nn.Module:
    """Train a fresh :class:`CornerNet` for ``pairs.patch`` on ``pairs`` (resuming from ``checkpoint`` when it exists).

    Step ``s`` trains on ``pairs.batch(numpy.random.default_rng([settings.seed, s]), settings.batch)``.

    Args:
        pairs: the data arm.
        settings: steps, batch, optimiser and seed.
        checkpoint: where to keep ``{"model", "optimizer", "schedule", "step", "seconds"}`` (``None``: nowhere).
        report: called as ``report(step, loss, seconds so far)`` every ``checkpoint_every`` steps.

    Returns:
        The trained network, in eval mode.
    """
    torch.manual_seed(settings.seed)
    network = CornerNet(pairs.patch, normalisation=settings.normalisation)
    optimizer = torch.optim.AdamW(network.parameters(), lr=settings.lr, weight_decay=settings.weight_decay)
    schedule = torch.optim.lr_scheduler.OneCycleLR(optimizer, settings.lr, total_steps=settings.steps,
                                                   pct_start=max(0.05, 2 / settings.steps))  # a warm-up of >= 2 steps
    step, seconds = 0, 0.0
    if checkpoint is not None and checkpoint.is_file():
        state = torch.load(checkpoint, map_location="cpu", weights_only=True)
        network.load_state_dict(state["model"])
        optimizer.load_state_dict(state["optimizer"])
        schedule.load_state_dict(state["schedule"])
        step, seconds = int(state["step"]), float(state["seconds"])
    network.train()
    running = []
    while step < settings.steps:
        start = time.perf_counter()
        source, target, offsets = pairs.batch(np.random.default_rng([settings.seed, step]), settings.batch)
        loss = corner_loss(network(source, target), offsets)
        optimizer.zero_grad()
        loss.backward()
        nn.utils.clip_grad_norm_(network.parameters(), 1.0)
        optimizer.step()
        schedule.step()
        step += 1
        seconds += time.perf_counter() - start
        running.append(loss.item())
        if step % settings.checkpoint_every == 0 or step == settings.steps:
            if checkpoint is not None:
                torch.save({"model": network.state_dict(), "optimizer": optimizer.state_dict(),
                            "schedule": schedule.state_dict(), "step": step, "seconds": seconds}, checkpoint)
            if report is not None:
                report(step, float(np.mean(running)), seconds)
            running = []
    return network.eval()
