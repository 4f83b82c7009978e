"""The shipped networks as estimators of :func:`sidar_torch.evaluate`: ``sidar-net`` and ``warp-net``.

Both are :class:`.network.CornerNet` with the same settings and budget, trained by
``python -m benchmarks.transfer train``: ``sidar-net`` on protocol pairs of rendered
``misaligned`` sequences, ``warp-net`` on the classic 2-D recipe on the same paintings
(docs/benchmarks.md says with which command, commit and SHA-256). Their weights ship in
``weights/`` beside this module.

An estimator maps ``(source, target)``, two ``(h, w, 3)`` uint8 RGB images, to the ``(3, 3)`` float64
homography from source to target pixels. The networks see 128 x 128 patches: other sizes are
resized to 128 x 128 (area filter when shrinking, bilinear otherwise) and the estimate is mapped back
to the images' pixels, so whole views work too, at the network's resolution.
"""

from __future__ import annotations

import hashlib
import json
from functools import lru_cache
from importlib import resources
from typing import Callable

import numpy as np
import torch
from torch.nn import functional as F

from .network import CornerNet
from .protocol import PATCH, patch_homography

__all__ = ["NETWORKS", "load_network", "network_estimator", "normalisation", "weights_sha256"]

NETWORKS = {"sidar-net": "sidar-net.pt", "warp-net": "warp-net.pt"}
"""Shipped network name -> its weights file in ``sidar_torch/deep_homography/weights``."""


def _weights(name: str):
    if name not in NETWORKS:
        raise ValueError(f"network: expected one of {sorted(NETWORKS)}, got {name!r}")
    return resources.files(__package__) / "weights" / NETWORKS[name]


def weights_sha256(name: str) -> str:
    """SHA-256 of the shipped weights file of network ``name``."""
    return hashlib.sha256(_weights(name).read_bytes()).hexdigest()


def normalisation(name: str) -> str:
    """The input normalisation the shipped network ``name`` was trained with (:data:`.network.NORMALISATIONS`),
    as ``weights/scores.json`` records it (``standardised`` where it does not say: the first weights')."""
    _weights(name)
    record = json.loads((resources.files(__package__) / "weights" / "scores.json").read_text())
    return record["networks"].get(name, {}).get("normalisation", "standardised")


@lru_cache(maxsize=None)
def load_network(name: str) -> CornerNet:
    """The shipped network ``name`` (:data:`NETWORKS`), in eval mode, on the CPU (loaded once per process)."""
    network = CornerNet(normalisation=normalisation(name))
    with _weights(name).open("rb") as file:
        network.load_state_dict(torch.load(file, map_location="cpu", weights_only=True))
    return network.eval()


def _to_patch(image: np.ndarray) -> torch.Tensor:
    """``(h, w, 3)`` uint8 -> ``(1, 3, PATCH, PATCH)`` float32 in [0, 1]."""
    if image.ndim != 3 or image.shape[2] != 3:
        raise ValueError(f"expected an (h, w, 3) RGB image, got shape {image.shape}")
    tensor = torch.from_numpy(np.ascontiguousarray(image)).permute(2, 0, 1)[None].float() / 255
    if tensor.shape[-2:] == (PATCH, PATCH):
        return tensor
    shrink = min(tensor.shape[-2:]) >= PATCH
    return F.interpolate(tensor, (PATCH, PATCH), mode="area" if shrink else "bilinear",
                         **({} if shrink else {"align_corners": False}))


def _patch_to_pixels(size: tuple[int, int]) -> np.ndarray:
    """``(3, 3)`` float64 from an ``(h, w)`` image's pixels to the resized patch's (pixel centres at integers
    in both): ``x_p = (x + 1/2) PATCH / w - 1/2``."""
    h, w = size
    return np.array([[PATCH / w, 0, PATCH / (2 * w) - 0.5], [0, PATCH / h, PATCH / (2 * h) - 0.5], [0, 0, 1]])


def network_estimator(name: str) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    """The estimator of the shipped network ``name`` (see the module docstring)."""

    @torch.no_grad()
    def estimate(source: np.ndarray, target: np.ndarray) -> np.ndarray:
        offsets = load_network(name)(_to_patch(source), _to_patch(target))[-1, 0].double().numpy()
        scale = _patch_to_pixels(source.shape[:2])
        return np.linalg.inv(scale) @ patch_homography(offsets, PATCH) @ scale

    estimate.__name__ = estimate.__qualname__ = name.replace("-", "_")
    return estimate
