"""Dense correspondence from depth: the math of :func:`sidar_torch.flow` and of the ``flow_to_reference``
output, float64 torch, on plain tensors (no sample keys; ``sidar_torch.sample.correspondence`` checks a
sample's and calls :func:`depth_flow`).

Pixels are Kornia's (pixel ``(u, v)`` is column u, row v; the top-left pixel's centre is ``(0, 0)``);
cameras OpenCV's (world point ``X`` lands at ``K (R X + t)``); depth the camera-frame z.
"""

from __future__ import annotations

import torch

__all__ = ["DEPTH_EDGE", "DEPTH_TOLERANCE", "depth_flow"]

DEPTH_TOLERANCE = 1e-3
"""Default relative disagreement allowed between the depth a point has in view j and the depth view j
rendered there (inverse depths interpolated bilinearly, exact on a plane) before the point counts
as hidden."""

DEPTH_EDGE = 0.05
"""Four neighbouring pixels whose inverse depths spread by more than this (relative to the largest)
straddle a depth edge (an occluder's outline): a point landing between them is not counted as
seen, even where the blend of both sides happens to match its depth."""


def depth_flow(depth: torch.Tensor, K: torch.Tensor, R: torch.Tensor, t: torch.Tensor, i: int, j: int,
               tolerance: float = DEPTH_TOLERANCE) -> tuple[torch.Tensor, torch.Tensor]:
    """Where every pixel of view ``i`` lands in view ``j``, and whether view ``j`` sees it there.

    Args:
        depth: ``(B, V, H, W)`` float64, camera-frame z (``inf``: nothing seen), ``H, W >= 2``.
        K, R: ``(B, V, 3, 3)``, t: ``(B, V, 3)`` float64, the cameras.
        i, j: view indices; tolerance: see :data:`DEPTH_TOLERANCE`.

    Returns:
        ``(B, 2, H, W)`` float64 flow in pixels (NaN where view i sees nothing) and ``(B, 1, H, W)``
        bool validity, as :func:`sidar_torch.flow` describes them.
    """
    B, _, H, W = depth.shape
    v, u = torch.meshgrid(torch.arange(H, dtype=torch.float64), torch.arange(W, dtype=torch.float64), indexing="ij")
    pixels = torch.stack([u, v, torch.ones_like(u)]).reshape(1, 3, H * W)
    z_i = depth[:, i].reshape(B, 1, H * W)
    seen = torch.isfinite(z_i)
    rays = torch.linalg.solve(K[:, i], pixels.expand(B, 3, H * W))  # (B, 3, HW), z = 1
    camera_i = rays * torch.where(seen, z_i, torch.zeros_like(z_i))
    world = R[:, i].transpose(1, 2) @ (camera_i - t[:, i, :, None])
    camera_j = R[:, j] @ world + t[:, j, :, None]
    ahead = camera_j[:, 2:] > 0
    projected = K[:, j] @ camera_j
    landed = projected[:, :2] / torch.where(ahead, projected[:, 2:], torch.ones_like(projected[:, 2:]))
    flows = torch.where(seen, landed - pixels[:, :2], torch.full_like(landed, float("nan")))
    agrees = _same_surface(depth[:, j], landed, camera_j[:, 2], tolerance)
    valid = seen & ahead & agrees[:, None]
    return flows.reshape(B, 2, H, W), valid.reshape(B, 1, H, W)


def _same_surface(depth_j: torch.Tensor, landed: torch.Tensor, z: torch.Tensor, tolerance: float) -> torch.Tensor:
    """``(B, N)`` bool: whether the four pixel centres of ``depth_j`` ``(B, H, W)`` around each point
    ``landed`` ``(B, 2, N)`` (pixels of view j) lie inside the grid and see a surface with no depth edge
    between them (:data:`DEPTH_EDGE`), and their inverse depths, interpolated bilinearly at the point (exact where they see one plane: inverse depth is
    affine in the pixels of a plane), agree with ``1 / z`` ``(B, N)`` within ``tolerance`` (relative)."""
    B, H, W = depth_j.shape
    x, y = landed[:, 0], landed[:, 1]
    inside = (x >= 0) & (x <= W - 1) & (y >= 0) & (y <= H - 1)
    x, y = x.where(inside, torch.zeros_like(x)), y.where(inside, torch.zeros_like(y))
    x0, y0 = x.floor().clamp(max=W - 2).long(), y.floor().clamp(max=H - 2).long()
    fx, fy = x - x0, y - y0
    inverse = depth_j.reshape(B, H * W).double().reciprocal()  # 0 where nothing is seen (inf)
    corners = [inverse.gather(1, (y0 + dy) * W + x0 + dx) for dy in (0, 1) for dx in (0, 1)]
    stacked = torch.stack(corners)
    seen = stacked.gt(0).all(0)
    smooth = stacked.min(0).values >= (1 - DEPTH_EDGE) * stacked.max(0).values
    interpolated = ((1 - fy) * ((1 - fx) * corners[0] + fx * corners[1])
                    + fy * ((1 - fx) * corners[2] + fx * corners[3]))
    return inside & seen & smooth & ((interpolated * z - 1).abs() <= tolerance)
