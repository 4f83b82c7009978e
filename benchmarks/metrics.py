"""How true the samples are: rendered pixels against homographies, and homographies against the
analytic ones.

* :func:`warp_residuals` warps view ``i`` into view ``j`` with the sample's ``H[i, j]``
  (``kornia.geometry.transform.warp_perspective``) and measures what is left: the sub-pixel
  displacement between the warped view and view ``j`` (translation-only Lucas-Kanade on
  square patches) and the photometric error, on pixels where both views see the painting,
  away from any border.
* :func:`homography_errors` compares every sample's float64 homographies (Kornia DLT) with
  the analytic plane-induced ones on a grid of painting points, and measures what the
  float32 tensors handed out add.
* :func:`psnr` compares two images (e.g. the label with the source painting).
* :func:`speckle_paintings` makes paintings on which the warp residual measures geometry.

``python -m benchmarks.accuracy_report`` prints them as a table; ``benchmarks.sweep`` and the accuracy tests use them too (they measure the package, they are not part of it).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import kornia
import numpy as np
import torch
import torch.nn.functional as F

from sidar_torch import geometry
from sidar_torch.sample import sequence_homographies
from sidar_torch.scene import SceneSequence

__all__ = [
    "HomographyError",
    "PairResidual",
    "homography_errors",
    "psnr",
    "speckle_paintings",
    "warp_residuals",
]


def speckle_paintings(count: int, size: tuple[int, int], seed: int = 0, scale: float = 1.5) -> torch.Tensor:
    """Paintings for measuring geometry: colour noise low-passed by a Gaussian of ``scale`` pixels.

    Every patch is textured in every direction (so Lucas-Kanade is well conditioned) and nothing
    is finer than the views can sample, so a residual measures geometry, not aliasing.

    Returns:
        ``(count, 3, H, W)`` float32 in [0, 1] (mean 0.5, standard deviation 0.18 before clipping).
    """
    noise = torch.randn(count, 3, *size, generator=torch.Generator().manual_seed(seed), dtype=torch.float64)
    kernel = 2 * math.ceil(3 * scale) + 1
    smooth = kornia.filters.gaussian_blur2d(noise, (kernel, kernel), (scale, scale), border_type="circular")
    return (smooth / smooth.std() * 0.18 + 0.5).clamp(0, 1).float()


def psnr(a: torch.Tensor, b: torch.Tensor) -> float:
    """Peak signal-to-noise ratio in dB of two images in [0, 1] (inf when equal)."""
    mse = float((a.double() - b.double()).square().mean())
    return math.inf if mse == 0 else 10 * math.log10(1 / mse)


@dataclass(frozen=True)
class PairResidual:
    """What remains after warping view ``i`` onto view ``j`` with ``H[i, j]``.

    Attributes:
        i, j: the view pair.
        displacements: ``(P, 2)`` float64, per textured patch the shift ``(du, dv)`` in view-j
            pixels that best aligns view j with the warped view i (0 for a perfect homography).
        centres: ``(P, 2)`` float64 patch centres in view-j pixels.
        photometric_mae: mean absolute difference (intensity in [0, 1], all channels) on the
            compared pixels.
        pixels: number of compared pixels.
    """

    i: int
    j: int
    displacements: np.ndarray
    centres: np.ndarray
    photometric_mae: float
    pixels: int

    @property
    def median(self) -> float:
        """Median displacement length over the patches, pixels (nan without patches)."""
        lengths = np.linalg.norm(self.displacements, axis=1)
        return float(np.median(lengths)) if len(lengths) else math.nan


def _erode(valid: torch.Tensor, radius: int) -> torch.Tensor:
    """``(N, 1, H, W)`` {0, 1} mask shrunk by ``radius`` pixels (square structuring element)."""
    return -F.max_pool2d(-valid, 2 * radius + 1, stride=1, padding=radius)


def _shift(image: torch.Tensor, flow: torch.Tensor) -> torch.Tensor:
    """Sample ``image (N, C, H, W)`` at ``x + flow`` (``flow (N, 2, H, W)`` pixels), bilinear."""
    n, _, h, w = image.shape
    grid = kornia.geometry.create_meshgrid(h, w, normalized_coordinates=False, device=image.device,
                                        dtype=image.dtype).permute(0, 3, 1, 2) + flow
    scale = torch.tensor([2 / max(w - 1, 1), 2 / max(h - 1, 1)], dtype=image.dtype).view(1, 2, 1, 1)
    return F.grid_sample(image, (grid * scale - 1).permute(0, 2, 3, 1), align_corners=True,
                         padding_mode="border")


def _source_density(H_target_to_source: torch.Tensor, h: int, w: int) -> torch.Tensor:
    """How many source pixels one target pixel spans, in its least stretched direction.

    The smaller singular value of the Jacobian of ``H_target_to_source`` (``(N, 3, 3)``) at every
    target pixel: where it is at least 1, the source holds all the detail the target shows.

    Returns:
        ``(N, 1, h, w)`` float64.
    """
    grid = kornia.geometry.create_meshgrid(h, w, normalized_coordinates=False, dtype=torch.float64)
    x = torch.cat([grid, torch.ones(1, h, w, 1, dtype=torch.float64)], dim=-1)  # (1, h, w, 3)
    y = torch.einsum("nab,hwb->nhwa", H_target_to_source, x[0])
    p = y[..., :2] / y[..., 2:]
    J = (H_target_to_source[:, None, None, :2, :2] - p[..., :, None] * H_target_to_source[:, None, None, 2:, :2]) / y[..., 2:, None]
    frobenius = J.square().sum((-2, -1))
    det = torch.linalg.det(J)
    smaller = (frobenius - torch.sqrt((frobenius.square() - 4 * det.square()).clamp(min=0))) / 2
    return smaller.clamp(min=0).sqrt()[:, None]


def patch_displacements(warped: torch.Tensor, target: torch.Tensor, valid: torch.Tensor,
                        patch: int = 16, iterations: int = 4,
                        min_texture: float = 1e-5) -> tuple[torch.Tensor, torch.Tensor]:
    """Per-patch translation between two aligned-looking images, by Lucas-Kanade.

    For every ``patch x patch`` tile lying wholly on ``valid`` pixels, finds the shift ``d``
    minimising ``sum (warped(x) - target(x + d))**2`` over the tile (Gauss-Newton, bilinear
    resampling of ``target``). Tiles whose structure tensor has its smaller eigenvalue below
    ``min_texture`` per pixel (flat or one-directional texture) are left out.

    Args:
        warped, target: ``(1, H, W)`` float64 grey images.
        valid: ``(1, H, W)`` {0, 1} pixels to compare.
        patch: tile side in pixels.
        iterations: Gauss-Newton steps.
        min_texture: least smaller eigenvalue of the mean structure tensor, (intensity/px)^2.

    Returns:
        ``(P, 2)`` shifts ``(du, dv)`` in pixels and ``(P, 2)`` tile centres ``(u, v)``.
    """
    warped, target, valid = warped[None], target[None], valid[None]
    whole = F.avg_pool2d(valid, patch, stride=patch) > 1 - 1e-9  # (1, 1, h', w') tiles fully valid
    flow = torch.zeros(1, 2, *whole.shape[-2:], dtype=target.dtype)
    for _ in range(iterations):
        dense = F.interpolate(flow, scale_factor=patch, mode="nearest")
        dense = F.pad(dense, (0, target.shape[-1] - dense.shape[-1], 0, target.shape[-2] - dense.shape[-2]))
        shifted = _shift(target, dense)
        gx, gy = kornia.filters.spatial_gradient(shifted, mode="diff", normalized=False)[:, :, :].unbind(2)
        gx, gy = gx / 2, gy / 2  # kornia's unnormalised 'diff' kernel is [-1, 0, 1]
        err = warped - shifted
        sums = [F.avg_pool2d(q, patch, stride=patch) for q in (gx * gx, gx * gy, gy * gy, gx * err, gy * err)]
        axx, axy, ayy, bx, by = sums
        det = axx * ayy - axy * axy
        det = torch.where(det.abs() > 0, det, torch.ones_like(det))
        flow = flow + torch.cat([(ayy * bx - axy * by) / det, (axx * by - axy * bx) / det], dim=1)
    smallest = (axx + ayy) / 2 - torch.sqrt(((axx - ayy) / 2) ** 2 + axy**2)
    keep = (whole & (smallest > min_texture))[0, 0]
    rows, cols = torch.nonzero(keep, as_tuple=True)
    centres = torch.stack([cols, rows], dim=1).to(target.dtype) * patch + (patch - 1) / 2
    return flow[0, :, rows, cols].T, centres


def warp_residuals(images: torch.Tensor, masks: torch.Tensor, homographies: torch.Tensor,
                   pairs: list[tuple[int, int]] | None = None, patch: int = 16, sigma: float = 1.0,
                   border: int = 3, min_density: float = 1.0) -> list[PairResidual]:
    """Residual displacement and photometric error of every view pair's warp (see module docstring).

    View ``i`` is warped into view ``j`` by ``warp_perspective(images[i], H[i, j], (H, W))``
    (bilinear). Compared pixels see the painting in view j (mask 0) and come from pixels of view
    i that see it, at least ``border`` pixels from anything else, and where view i samples the
    painting at least as densely as view j (one view-j pixel spans at least ``min_density``
    view-i pixels in every direction): where the warp magnifies, view i has lost detail that
    view j shows, and the comparison would measure aliasing rather than geometry. The other
    direction, ``(j, i)``, measures those places. Both images are blurred with a Gaussian of
    ``sigma`` pixels before Lucas-Kanade.

    Args:
        images: ``(V, 3, H, W)`` float in [0, 1].
        masks: ``(V, 1, H, W)``, 1 where the painting is not visible.
        homographies: ``(V, V, 3, 3)``, ``H[i, j]`` from view i to view j.
        pairs: ordered pairs ``(i, j)`` to measure (default every ``i != j``).
        patch: Lucas-Kanade tile side, pixels (8-pixel tiles let 8-bit noise through: up to 0.4 px).
        sigma: Gaussian blur, pixels.
        border: pixels kept from the painting's border, occluders and the image edge.
        min_density: least view-i pixels per view-j pixel (smaller singular value of the warp's
            Jacobian) for a pixel to be compared.

    Returns:
        One :class:`PairResidual` per pair.
    """
    images, masks, homographies = images.double(), masks.double(), homographies.double()
    v, _, h, w = images.shape
    pairs = [(i, j) for i in range(v) for j in range(v) if i != j] if pairs is None else pairs
    src = torch.stack([images[i] for i, _ in pairs])
    seen = torch.stack([1 - masks[i] for i, _ in pairs])
    H = torch.stack([homographies[i, j] for i, j in pairs])
    warped = kornia.geometry.transform.warp_perspective(src, H, (h, w), align_corners=True)
    seen = kornia.geometry.transform.warp_perspective(seen, H, (h, w), align_corners=True, padding_mode="zeros")
    target = torch.stack([images[j] for _, j in pairs])
    valid = (seen > 1 - 1e-6).double() * torch.stack([1 - masks[j] for _, j in pairs])
    valid = valid * (_source_density(torch.stack([homographies[j, i] for i, j in pairs]), h, w) >= min_density)
    valid = F.pad(valid[..., 1:-1, 1:-1], (1, 1, 1, 1))  # the image edge is a border too
    radius = border + math.ceil(3 * sigma)  # the blur must not reach past the compared pixels
    valid = _erode(valid, radius)
    kernel = 2 * math.ceil(3 * sigma) + 1
    grey = kornia.filters.gaussian_blur2d(torch.cat([warped, target]).mean(1, keepdim=True),
                                          (kernel, kernel), (sigma, sigma))
    results = []
    for k, (i, j) in enumerate(pairs):
        shift, centres = patch_displacements(grey[k], grey[len(pairs) + k], valid[k], patch)
        pixels = int(valid[k].sum())
        mae = float(((warped[k] - target[k]).abs() * valid[k]).sum() / max(3 * pixels, 1))
        results.append(PairResidual(i, j, shift.numpy(), centres.numpy(), mae, pixels))
    return results


@dataclass(frozen=True)
class HomographyError:
    """How far one sample's handed-out homographies are from the true ones, in pixels of the target
    view, over painting points visible in both views of every pair.

    Attributes:
        float64: largest distance between the Kornia-DLT homographies (float64) and the analytic
            plane-induced ones.
        float32: largest distance between the float32 homographies the dataset hands out and
            the analytic ones.
        cycle32: largest entry of ``H[i, j] @ H[j, i] - I`` in float32.
        pairs: ordered pairs with at least one commonly visible point.
    """

    float64: float
    float32: float
    cycle32: float
    pairs: int


def homography_errors(sequence: SceneSequence, grid: int = 17) -> HomographyError:
    """Compare a sequence's homographies (as :func:`sidar_torch.sample.sequence_homographies`
    computes them) with the analytic plane-induced ones at the painting points of a
    ``grid x grid`` lattice that both views of a pair see."""
    H64, _ = sequence_homographies(sequence)
    K, R, t = sequence.cameras()
    truth = geometry.plane_induced_homographies(K, R, t)
    pixels, inside = geometry.visible_plane_points(K, R, t, sequence.image_size, grid)
    both = geometry.shared_points(inside)
    H32 = H64.float()
    cycle = (H32 @ H32.transpose(0, 1) - torch.eye(3)).abs().amax().item()
    return HomographyError(geometry.point_disagreement(H64.numpy(), truth, pixels, both),
                           geometry.point_disagreement(H32.double().numpy(), truth, pixels, both),
                           cycle, int(both.any(-1).sum()))
