"""The patch-pair protocol: deep-homography pairs cut from real multi-view data.

For a pair of views ``(i, j)`` of a sequence with a known homography ``H_ij`` (view-i pixels to
view-j pixels), a ``P x P`` box is placed in view ``i`` on the visible painting and its four
corners are moved by a random perturbation of at most ``rho`` pixels per coordinate (DeTone et al.
2016; IHN): ``Q`` is the homography that moves them, in view i's pixels. The pair is

- ``source``: the box of view ``i``;
- ``target``: the same box of view ``j`` brought into view i's frame by ``H_ij`` and moved by ``Q``,
  i.e. ``target(y) = view_j(H_ij Q^-1 y)`` for every box pixel ``y`` (bilinear, zero outside view j).

The geometric truth of the pair is ``Q`` alone (in patch coordinates); every other difference
between the two patches (light, shadow, highlight, occluder, resampling, noise) is the real
difference between the two views. A view pair whose homography is the identity and whose second
view is a photometric copy of the first is the classic 2-D recipe (:mod:`.warps`).

Conventions (the package's): pixel ``(u, v)`` is column ``u``, row ``v``, the centre of the top-left
pixel is ``(0, 0)``; corners are listed top-left, top-right, bottom-right, bottom-left at the
centres of the box's corner pixels (``homography_pairs``' convention); offsets are
``(du, dv)`` pixels.

Pairs are drawn by a seeded rule (:func:`draw_pairs`): for sequence ``k`` of a set, the generator
``numpy.random.default_rng([seed, k])`` visits every ordered view pair ``(i, j)``, ``i != j``, in
order and draws up to ``attempts`` candidates (box and perturbation) for it, keeping the first whose
two patches both show the painting on at least ``min_visible`` of their pixels (masks 0); a view
pair with no such candidate is left out. The pairs depend on the data and the seed only, so every
estimator is scored on the same pairs.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Iterator, Mapping

import kornia
import numpy as np
import torch

__all__ = ["MIN_VISIBLE", "PATCH", "RHO", "PatchPair", "cut_pair", "draw_pair", "draw_pairs", "patch_homography",
           "visible_fractions"]

PATCH = 128
"""Default patch side (pixels): the size deep homography networks are trained and scored at."""

RHO = 32
"""Default largest corner perturbation per coordinate (pixels): the DeTone / IHN range for 128 px patches."""

MIN_VISIBLE = 0.5
"""Default least fraction of each patch's pixels that must show the painting."""

ATTEMPTS = 10
"""Candidates (box and perturbation) drawn per view pair before it is left out."""


@dataclass(frozen=True)
class PatchPair:
    """One pair of the protocol.

    Attributes:
        sequence: the sequence's index in its set.
        source, target: the view indices ``i`` and ``j``.
        origin: ``(u0, v0)``, column and row of the box's top-left pixel in view ``i``.
        offsets: ``(4, 2)`` float64 pixels, the perturbation of the box's corners (TL, TR, BR, BL; du, dv).
        patch: the box's side in pixels.
    """

    sequence: int
    source: int
    target: int
    origin: tuple[int, int]
    offsets: np.ndarray
    patch: int


def box_corners(patch: int) -> np.ndarray:
    """``(4, 2)`` float64: the centres of a ``patch x patch`` box's corner pixels, TL, TR, BR, BL."""
    side = patch - 1.0
    return np.array([[0.0, 0.0], [side, 0.0], [side, side], [0.0, side]])


def patch_homography(offsets: np.ndarray | torch.Tensor, patch: int) -> np.ndarray:
    """The pair's truth ``Q`` in patch coordinates, ``(3, 3)`` float64 with det 1: source-patch pixels
    to target-patch pixels, sending each corner of :func:`box_corners` to itself plus ``offsets (4, 2)``."""
    corners = torch.from_numpy(box_corners(patch))[None]
    moved = corners + torch.as_tensor(np.asarray(offsets, np.float64))[None]
    Q = kornia.geometry.transform.get_perspective_transform(corners, moved)[0].numpy()
    return Q / np.cbrt(np.linalg.det(Q))


def _translation(origin: tuple[int, int]) -> np.ndarray:
    """Patch pixels to view pixels for a box whose top-left pixel is ``origin``: ``(3, 3)`` float64."""
    return np.array([[1.0, 0.0, origin[0]], [0.0, 1.0, origin[1]], [0.0, 0.0, 1.0]])


def _target_map(H_ij: np.ndarray, pair: PatchPair) -> np.ndarray:
    """``M (3, 3)`` float64 with ``target(y) = view_j(M^-1 y)``: view-j pixels to target-patch pixels,
    ``Q T^-1 H_ij^-1`` (``T``: patch to view-i pixels)."""
    return patch_homography(pair.offsets, pair.patch) @ np.linalg.inv(_translation(pair.origin)) @ np.linalg.inv(H_ij)


def _warp(view: torch.Tensor, M: np.ndarray, patch: int) -> torch.Tensor:
    """``(C, patch, patch)``: ``view (C, H, W)`` float sampled at ``M^-1 y`` (bilinear, 0 outside), in the
    view's dtype (float32 places a sample within about 1e-4 px at these sizes)."""
    matrix = torch.from_numpy(M).to(view.dtype)[None]
    return kornia.geometry.transform.warp_perspective(view[None], matrix, (patch, patch), align_corners=True,
                                                      padding_mode="zeros")[0]


def cut_pair(images: torch.Tensor, H_ij: np.ndarray, pair: PatchPair) -> dict[str, Any]:
    """The two patches of ``pair`` and its truth.

    Args:
        images: ``(V, C, H, W)`` float, the sequence's views (``C = 3``: RGB in [0, 1]).
        H_ij: ``(3, 3)`` view-i to view-j pixels (any scale).
        pair: where to cut (from :func:`draw_pairs`).

    Returns:
        ``source``, ``target``: ``(C, P, P)`` in the images' dtype; ``H``: ``(3, 3)`` float64, the truth
        (source-patch to target-patch pixels, det 1).
    """
    u0, v0, P = pair.origin[0], pair.origin[1], pair.patch
    return {"source": images[pair.source, :, v0:v0 + P, u0:u0 + P],
            "target": _warp(images[pair.target], _target_map(H_ij, pair), P),
            "H": patch_homography(pair.offsets, P)}


def visible_fractions(masks: torch.Tensor, H_ij: np.ndarray, pair: PatchPair) -> tuple[float, float]:
    """The fractions of the source and target patches of ``pair`` that show the painting, from
    ``masks (V, 1, H, W)`` in {0, 1} (1: not visible); target pixels outside view j do not."""
    return _fractions(1.0 - masks.float(), H_ij, pair)


def _fractions(seen: torch.Tensor, H_ij: np.ndarray, pair: PatchPair) -> tuple[float, float]:
    """:func:`visible_fractions` from ``seen = 1 - masks`` (computed once for all of a view pair's candidates)."""
    cut = cut_pair(seen, H_ij, pair)
    return float(cut["source"].mean()), float((cut["target"] > 0.5).double().mean())


def _check(name: str, value: Any, low: float, high: float) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
            or not low <= value <= high:
        raise ValueError(f"{name}: expected a number in [{low:g}, {high:g}], got {value!r}")


def draw_pairs(sample: Mapping[str, Any], sequence: int, seed: int = 0, patch: int = PATCH, rho: float = RHO,
               min_visible: float = MIN_VISIBLE, attempts: int = ATTEMPTS) -> Iterator[PatchPair]:
    """The protocol's pairs of one sequence (see the module docstring for the rule).

    Args:
        sample: ``images (V, 3, H, W)``, ``masks (V, 1, H, W)``, ``homographies (V, V, 3, 3)``.
        sequence: the sequence's index in its set (with ``seed``, it seeds the draws).
        seed: the protocol's seed.
        patch: the box's side, pixels; ``H`` and ``W`` must be at least ``patch + 2 rho``.
        rho: the largest corner perturbation per coordinate, pixels (``>= 0``).
        min_visible: least fraction of each patch that must show the painting, in [0, 1].
        attempts: candidates per view pair, ``>= 1``.

    Yields:
        :class:`PatchPair`, in view-pair order.

    Raises:
        ValueError: a bad argument, or views too small for the box and its perturbation.
    """
    images = sample["images"]
    V, _, H, W = images.shape
    _check("patch", patch, 2, min(H, W))
    _check("rho", rho, 0, (min(H, W) - patch) / 2)
    _check("min_visible", min_visible, 0, 1)
    _check("attempts", attempts, 1, 1000)
    rng = np.random.default_rng([seed, sequence])
    for i in range(V):
        for j in range(V):
            if i != j:
                pair = draw_pair(sample, sequence, i, j, rng, patch, rho, min_visible, attempts)
                if pair is not None:
                    yield pair


def draw_pair(sample: Mapping[str, Any], sequence: int, i: int, j: int, rng: np.random.Generator,
              patch: int = PATCH, rho: float = RHO, min_visible: float = MIN_VISIBLE,
              attempts: int = ATTEMPTS) -> PatchPair | None:
    """One pair of views ``i -> j`` of ``sample`` (keys as in :func:`draw_pairs`, arguments unchecked):
    the first of up to ``attempts`` candidates drawn with ``rng`` (box origin uniform with a margin of
    ``ceil(rho)`` pixels inside the view, each offset uniform in ``[-rho, rho]``) whose patches both
    show the painting on at least ``min_visible`` of their pixels; ``None`` if none does."""
    _, _, H, W = sample["images"].shape
    seen = 1.0 - sample["masks"].float()
    H_ij = sample["homographies"][i, j].double().numpy()
    margin = int(np.ceil(rho))
    for _ in range(attempts):
        origin = (int(rng.integers(margin, W - patch - margin + 1)), int(rng.integers(margin, H - patch - margin + 1)))
        pair = PatchPair(sequence, i, j, origin, rng.uniform(-rho, rho, (4, 2)), patch)
        if min(_fractions(seen, H_ij, pair)) >= min_visible:
            return pair
    return None
