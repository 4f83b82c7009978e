"""Homography-network pairs from SIDAR samples: two views, a patch, ``H_ab``, four-corner offsets.

:func:`homography_pairs` turns a sample or a batch (from :class:`sidar_torch.SidarDataset` or
:class:`sidar_torch.SidarAugment`) into the training pairs of HomographyNet-style models
(DeTone et al. 2016): a patch of view ``a``, the same pixel box of view ``b``, and the homography
between them, both as a matrix and as the displacement of the patch's four corners.

Conventions (the package's): pixel ``(u, v)`` is column ``u``, row ``v``, the centre of the
top-left pixel is ``(0, 0)`` (Kornia); ``H_ab`` maps view-a pixel coordinates to view-b pixel
coordinates, so ``kornia.geometry.transform.warp_perspective(view_a, H_ab, (H, W))`` lands on
view ``b`` wherever the painting is visible in both.
"""

from __future__ import annotations

import operator
from typing import Any, Mapping

import kornia
import torch

from ..config import as_int
from ..sample.correspondence import FLOW_SOURCE, flow
from ..sample import KEYS, float_tensor

__all__ = ["homography_pairs"]

PAIRED_VIEW_KEYS = tuple(key.name for key in KEYS if key.switch is not None and key.shape.startswith("(V, ")
                         and key.shape.endswith("H, W)"))
"""The optional per-view images of the sample table (``opacities``, ``shadow_masks``, ``shadow_free``, ``depth``,
``flow_to_reference``, ``distortion_maps``):
when a batch holds one, the pair carries the same boxes of it."""


def homography_pairs(batch: Mapping[str, Any], patch_size: int | tuple[int, int], *,
                     generator: torch.Generator | None = None, views: tuple[int, int] | None = None,
                     min_valid: float = 0.0, attempts: int = 16) -> dict[str, torch.Tensor]:
    """Cut one homography-network pair out of every item of a batch.

    For each item a pair of views ``a != b`` (uniform over ordered pairs, view 0 included, unless
    ``views`` fixes them) and a patch position (uniform over the positions that keep the patch
    inside the image) are drawn. With ``min_valid > 0``, ``attempts`` candidates are drawn per item
    and the first whose ``valid`` fraction reaches ``min_valid`` is kept (else the one with the
    largest fraction); the number of draws does not depend on the images, so the choice is a
    function of the generator's state and the batch.

    Args:
        batch: a dict with ``images`` ``(B, V, 3, H, W)``, ``masks`` ``(B, V, 1, H, W)`` and
            ``homographies`` ``(B, V, V, 3, 3)`` (``V >= 2``), or one sample with these shapes
            without ``B`` (the outputs then have no ``B`` either). Any device, float dtype.
        patch_size: ``(ph, pw)`` (or one int for a square), ``2 <= ph <= H``, ``2 <= pw <= W``.
        generator: ``torch.Generator`` for the draws (``None``: PyTorch's global generator).
        views: ``(a, b)`` to use for every item instead of drawing them.
        min_valid: least fraction of valid patch pixels wanted, in [0, 1].
        attempts: candidates drawn per item when ``min_valid > 0``.

    Returns:
        A dict of tensors on the batch's device (patches and ``valid`` in the images' dtype,
        homographies, corners and offsets in the homographies' dtype):

        - ``patch_a``, ``patch_b`` ``(B, 3, ph, pw)``: the pixel box with top-left pixel
          ``origin`` in view ``a`` and in view ``b``.
        - ``H_ab`` ``(B, 3, 3)``: view-a to view-b pixels, full-image coordinates
          (``homographies[:, a, b]``, det = 1).
        - ``H_patch`` ``(B, 3, 3)``: patch_a to patch_b pixels, ``T^-1 H_ab T`` with ``T`` the
          translation by ``origin`` (det = 1); ``warp_perspective(patch_a, H_patch, (ph, pw))`` lands on
          ``patch_b`` where the moved pixels stay inside the box and are valid.
        - ``corners`` ``(B, 4, 2)``: the patch's corners in view a, full-image ``(u, v)``: the
          centres of its corner pixels, in the order top-left, top-right, bottom-right,
          bottom-left (clockwise on screen), i.e. ``origin + [(0, 0), (pw-1, 0), (pw-1, ph-1), (0, ph-1)]``.
        - ``corner_offsets`` ``(B, 4, 2)``: where ``H_ab`` sends each corner minus the corner
          (HomographyNet's 4-point parametrisation; the same in patch coordinates).
          ``kornia.geometry.transform.get_perspective_transform(c, c + corner_offsets)`` with
          ``c = corners - origin`` gives ``H_patch`` up to scale. Corners off the painting, or
          behind camera b, can have huge or meaningless offsets: check ``valid``.
        - ``valid`` ``(B, 1, ph, pw)`` in {0, 1}: 1 where the patch pixel of view a sees the
          painting (mask 0) and ``H_ab`` sends it in front of camera b into a pixel of view b
          (the pixel whose centre is nearest, inside the image) where the painting is visible.
          Pixels next to an occluder's edge are valid but their bilinear neighbours may not be;
          erode ``valid`` if a loss must ignore them.
        - ``views`` ``(B, 2)`` int64: ``(a, b)``.
        - ``origin`` ``(B, 2)`` int64: ``(u0, v0)``, column and row of the patch's top-left pixel.
        - ``<key>_a``, ``<key>_b`` ``(B, C, ph, pw)``: for each optional per-view key the batch holds
          (``opacities``, ``shadow_masks``, ``shadow_free``, ``depth``, see :data:`PAIRED_VIEW_KEYS`), the
          same pixel boxes of it, e.g. ``shadow_free_a`` and ``shadow_free_b``.
        - ``flow_ab`` ``(B, 2, ph, pw)`` float32 and ``flow_valid`` ``(B, 1, ph, pw)`` in {0, 1}, when the
          batch holds ``depth`` (config ``depth_output``; with its ``K``, ``R``, ``t``): where each patch
          pixel of view a lands in view b minus the pixel, full-image pixels, and where that is a true,
          unhidden correspondence (:func:`sidar_torch.flow`): on occluders of a static scene it carries
          the parallax ``H_ab`` lacks.
        - ``lens_a``, ``lens_b`` ``(B, 5)`` float64, when the batch holds ``lens``: the two views' lenses.
          The patches are then cut from the distorted views while ``H_ab`` maps the undistorted ones:
          pass ``sidar_torch.undistort``'s images and masks for pairs that ``H_ab`` aligns exactly.

    Raises:
        KeyError: a required key is missing.
        ValueError: inconsistent shapes, ``V < 2``, bad ``patch_size``, ``views``, ``min_valid``
            or ``attempts``.
        TypeError: ``generator`` is not a ``torch.Generator``.
    """
    images, masks, homographies, single = _check_batch(batch)
    B, V, _, H, W = images.shape
    ph, pw = _check_patch_size(patch_size, (H, W))
    if isinstance(min_valid, bool) or not isinstance(min_valid, (int, float)) or not 0.0 <= min_valid <= 1.0:
        raise ValueError(f"min_valid: expected a fraction in [0, 1], got {min_valid!r}")
    if generator is not None and not isinstance(generator, torch.Generator):
        raise TypeError(f"generator: expected a torch.Generator or None, got {type(generator).__name__}")
    attempts = as_int("attempts", attempts, 1)
    tries = attempts if min_valid > 0 else 1
    device, dtype = images.device, homographies.dtype

    def draw(high: int, shape: tuple[int, ...]) -> torch.Tensor:
        gen_device = generator.device if generator is not None else "cpu"
        return torch.randint(0, high, shape, generator=generator, device=gen_device).to(device)

    # Candidates (B, tries): view pair, patch origin.
    if views is None:
        a = draw(V, (B, tries))
        b = draw(V - 1, (B, tries))
        b = b + (b >= a).long()  # uniform over the V - 1 views other than a
    else:
        a_fixed, b_fixed = _check_views(views, V)
        a = torch.full((B, tries), a_fixed, device=device)
        b = torch.full((B, tries), b_fixed, device=device)
    u0 = draw(W - pw + 1, (B, tries))
    v0 = draw(H - ph + 1, (B, tries))

    item = torch.arange(B, device=device)[:, None].expand(B, tries)
    H_ab = homographies[item, a, b]  # (B, tries, 3, 3)
    valid = _valid(masks[item, a], masks[item, b], H_ab, u0, v0, (ph, pw))  # (B, tries, ph, pw)
    if tries > 1:
        fraction = valid.flatten(2).mean(2, dtype=torch.float32)
        good = fraction >= min_valid
        pick = torch.where(good.any(1), good.float().argmax(1), fraction.argmax(1))
    else:
        pick = torch.zeros(B, dtype=torch.long, device=device)
    rows = torch.arange(B, device=device)
    a, b, u0, v0 = a[rows, pick], b[rows, pick], u0[rows, pick], v0[rows, pick]
    H_ab, valid = H_ab[rows, pick], valid[rows, pick]

    origin = torch.stack([u0, v0], 1)  # (B, 2)
    T = torch.eye(3, dtype=dtype, device=device).repeat(B, 1, 1)
    T[:, :2, 2] = origin.to(dtype)
    T_inv = T.clone()
    T_inv[:, :2, 2] = -origin.to(dtype)
    H_patch = T_inv @ H_ab @ T

    box = torch.tensor([[0, 0], [pw - 1, 0], [pw - 1, ph - 1], [0, ph - 1]], dtype=dtype, device=device)
    corners = origin.to(dtype)[:, None] + box  # (B, 4, 2)
    corner_offsets = kornia.geometry.linalg.transform_points(H_ab, corners) - corners

    out = {
        "patch_a": _crop(images[rows, a], u0, v0, (ph, pw)),
        "patch_b": _crop(images[rows, b], u0, v0, (ph, pw)),
        "H_ab": H_ab,
        "H_patch": H_patch,
        "corners": corners,
        "corner_offsets": corner_offsets,
        "valid": valid[:, None].to(images.dtype),
        "views": torch.stack([a, b], 1),
        "origin": origin,
    }
    if "lens" in batch:  # the patches are of the distorted views; H_ab maps the undistorted ones
        lens = batch["lens"][None] if single else batch["lens"]
        out["lens_a"], out["lens_b"] = lens[rows, a], lens[rows, b]
    for name in PAIRED_VIEW_KEYS:
        if name in batch:
            values = _per_view_tensor(batch, name, images, single)
            out[f"{name}_a"] = _crop(values[rows, a], u0, v0, (ph, pw))
            out[f"{name}_b"] = _crop(values[rows, b], u0, v0, (ph, pw))
    if FLOW_SOURCE in batch:
        flows, seen = _flows(batch, single, a, b)
        out["flow_ab"] = _crop(flows, u0, v0, (ph, pw))
        out["flow_valid"] = _crop(seen, u0, v0, (ph, pw)).to(images.dtype)
    return {key: value[0] for key, value in out.items()} if single else out


def _valid(mask_a: torch.Tensor, mask_b: torch.Tensor, H_ab: torch.Tensor, u0: torch.Tensor, v0: torch.Tensor,
           patch: tuple[int, int]) -> torch.Tensor:
    """Valid-pixel masks of candidate patches (see :func:`homography_pairs`).

    Args:
        mask_a, mask_b: ``(..., 1, H, W)`` masks of views a and b (1 = painting not visible).
        H_ab: ``(..., 3, 3)``; u0, v0: ``(...)`` patch origins (int64).
        patch: ``(ph, pw)``.

    Returns:
        ``(..., ph, pw)`` bool.
    """
    ph, pw = patch
    H, W = mask_a.shape[-2:]
    lead = u0.shape
    ys = v0[..., None, None] + torch.arange(ph, device=u0.device)[:, None]  # (..., ph, 1)
    xs = u0[..., None, None] + torch.arange(pw, device=u0.device)  # (..., 1, pw)
    seen_a = _gather(mask_a[..., 0, :, :], ys.expand(*lead, ph, pw), xs.expand(*lead, ph, pw)) == 0

    pixels = torch.stack(torch.broadcast_tensors(xs, ys), -1).to(H_ab.dtype)  # (..., ph, pw, 2) (u, v)
    homogeneous = kornia.geometry.conversions.convert_points_to_homogeneous(pixels.flatten(-3, -2))
    mapped = homogeneous @ H_ab.transpose(-1, -2)  # (..., ph * pw, 3)
    w = mapped[..., 2]
    ahead = w > 0  # with det(H_ab) = 1, points behind camera b get w < 0 (the map flips orientation there)
    uv = mapped[..., :2] / torch.where(ahead, w, torch.ones_like(w))[..., None]
    col, row = (uv + 0.5).floor().unbind(-1)  # the pixel whose centre is nearest
    inside = ahead & (col >= 0) & (col <= W - 1) & (row >= 0) & (row <= H - 1)
    col = torch.where(inside, col, torch.zeros_like(col)).long()
    row = torch.where(inside, row, torch.zeros_like(row)).long()
    seen_b = inside & (_gather(mask_b[..., 0, :, :], row, col) == 0)
    return seen_a & seen_b.unflatten(-1, (ph, pw))


def _flows(batch: Mapping[str, Any], single: bool, a: torch.Tensor, b: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """``(B, 2, H, W)`` float32 flow from view ``a[k]`` to view ``b[k]`` of each item and ``(B, 1, H, W)``
    bool its validity (:func:`sidar_torch.flow`, from the batch's ``depth`` and cameras)."""
    pairs = []
    for k, (i, j) in enumerate(zip(a.tolist(), b.tolist())):
        item = batch if single else {name: value[k] for name, value in batch.items()
                                     if isinstance(value, torch.Tensor) and value.ndim > 0}
        pairs.append(flow(item, i, j))
    return torch.stack([f for f, _ in pairs]), torch.stack([v for _, v in pairs])


def _gather(mask: torch.Tensor, rows: torch.Tensor, cols: torch.Tensor) -> torch.Tensor:
    """``mask[..., rows, cols]`` per leading index: ``mask`` ``(..., H, W)``, indices ``(..., *s)``."""
    W = mask.shape[-1]
    flat = (rows * W + cols).flatten(len(mask.shape) - 2)
    return mask.flatten(-2).gather(-1, flat).reshape(rows.shape)


def _crop(images: torch.Tensor, u0: torch.Tensor, v0: torch.Tensor, patch: tuple[int, int]) -> torch.Tensor:
    """``(B, C, ph, pw)`` boxes of ``images`` ``(B, C, H, W)`` with top-left pixels ``(u0, v0)``."""
    ph, pw = patch
    rows = (v0[:, None] + torch.arange(ph, device=v0.device))[:, :, None]  # (B, ph, 1)
    cols = (u0[:, None] + torch.arange(pw, device=u0.device))[:, None, :]  # (B, 1, pw)
    item = torch.arange(len(images), device=images.device)[:, None, None]
    return images.permute(0, 2, 3, 1)[item, rows, cols].permute(0, 3, 1, 2)  # (B, ph, pw, C) -> (B, C, ph, pw)


def _check_batch(batch: Mapping[str, Any]) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, bool]:
    if not isinstance(batch, Mapping):
        raise TypeError(f"batch: expected a dict with images, masks and homographies, got {type(batch).__name__}")
    images = _float_tensor(batch, "images")
    masks = _float_tensor(batch, "masks")
    homographies = _float_tensor(batch, "homographies")
    single = images.ndim == 4
    if single:
        images, masks, homographies = images[None], masks[None], homographies[None]
    if images.ndim != 5 or images.shape[2] != 3:
        raise ValueError(f"batch['images']: expected (B, V, 3, H, W) or (V, 3, H, W), got {tuple(batch['images'].shape)}")
    B, V, _, H, W = images.shape
    if tuple(masks.shape) != (B, V, 1, H, W):
        raise ValueError(f"batch['masks']: expected {(B, V, 1, H, W)[1 if single else 0:]} to match images, "
                         f"got {tuple(batch['masks'].shape)}")
    if tuple(homographies.shape) != (B, V, V, 3, 3):
        raise ValueError(f"batch['homographies']: expected {(B, V, V, 3, 3)[1 if single else 0:]} to match "
                         f"images, got {tuple(batch['homographies'].shape)}")
    if V < 2:
        raise ValueError(f"batch['images']: expected at least 2 views to make a pair, got V = {V}")
    if B < 1:
        raise ValueError("batch['images']: expected at least one item, got an empty batch")
    if len({images.device, masks.device, homographies.device}) != 1:
        raise ValueError("batch: images, masks and homographies must be on one device, got "
                         f"{images.device}, {masks.device}, {homographies.device}")
    return images, masks, homographies, single


def _per_view_tensor(batch: Mapping[str, Any], key: str, images: torch.Tensor, single: bool) -> torch.Tensor:
    """``batch[key]`` as ``(B, V, C, H, W)``, checked against ``images`` ``(B, V, 3, H, W)``."""
    values = _float_tensor(batch, key)
    values = values[None] if single else values
    B, V, _, H, W = images.shape
    if values.ndim != 5 or values.shape[:2] != (B, V) or values.shape[3:] != (H, W):
        raise ValueError(f"batch[{key!r}]: expected {('B', V, 'C', H, W)[1 if single else 0:]} to match images, "
                         f"got {tuple(batch[key].shape)}")
    if values.device != images.device:
        raise ValueError(f"batch[{key!r}]: expected the images' device {images.device}, got {values.device}")
    return values


def _float_tensor(batch: Mapping[str, Any], key: str) -> torch.Tensor:
    return float_tensor(batch, key, "images, masks, homographies")


def _check_patch_size(patch_size: Any, image_size: tuple[int, int]) -> tuple[int, int]:
    H, W = image_size
    try:
        if isinstance(patch_size, bool):
            raise TypeError
        ph, pw = (patch_size, patch_size) if isinstance(patch_size, int) else patch_size
        if isinstance(ph, bool) or isinstance(pw, bool):
            raise TypeError
        ph, pw = operator.index(ph), operator.index(pw)
    except (TypeError, ValueError):
        raise ValueError(f"patch_size: expected (ph, pw) or one int, got {patch_size!r}") from None
    if not (2 <= ph <= H and 2 <= pw <= W):
        raise ValueError(f"patch_size: expected 2 <= ph <= {H} and 2 <= pw <= {W} (the image size), "
                         f"got {(ph, pw)}")
    return ph, pw


def _check_views(views: Any, n_views: int) -> tuple[int, int]:
    try:
        a, b = views
        a, b = operator.index(a), operator.index(b)
    except (TypeError, ValueError):
        raise ValueError(f"views: expected a pair (a, b) of view indices, got {views!r}") from None
    if not (0 <= a < n_views and 0 <= b < n_views and a != b):
        raise ValueError(f"views: expected two different view indices in [0, {n_views}), got {views!r}")
    return a, b
