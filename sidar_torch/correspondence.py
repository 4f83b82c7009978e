"""Dense correspondence from rendered depth: where each pixel's surface point lands in another view.

A sample rendered with ``depth_output`` holds, per view, the distance along the camera's z axis to
the surface each pixel centre sees (``depth``), and the cameras (``K``, ``R``, ``t``: world point ``X``
lands at ``K (R X + t)``). :func:`flow` lifts every pixel of view i to its 3-D point and projects it
into view j: on the painting that is the homography ``H[i, j]`` (to float32 depth's rounding); on an
occluder of a static scene (``scene_per_view: false``) it carries the parallax the homography lacks.

Pixels are Kornia's (pixel ``(u, v)`` is column u, row v; the top-left pixel's centre is ``(0, 0)``);
all arithmetic is float64.
"""

from __future__ import annotations

from typing import Any, Mapping

import torch

from .dense import DEPTH_EDGE, DEPTH_TOLERANCE, depth_flow
from .sample import KEYS, float_tensor

__all__ = ["DEPTH_EDGE", "DEPTH_TOLERANCE", "flow"]


def flow(sample: Mapping[str, Any], i: int, j: int, tolerance: float = DEPTH_TOLERANCE
         ) -> tuple[torch.Tensor, torch.Tensor]:
    """Where every pixel of view ``i`` lands in view ``j``, and whether view ``j`` sees it there.

    Args:
        sample: a sample dict with ``depth`` (``(V, 1, H, W)``, config ``depth_output``), ``K``, ``R``
            ``(V, 3, 3)`` and ``t`` ``(V, 3)``, or a batch of them (a leading ``B`` on each).
        i, j: the two views (``0 <= i, j < V``).
        tolerance: the relative depth disagreement (see :data:`DEPTH_TOLERANCE`) that still counts as
            the same surface.

    Returns:
        ``flow`` ``(2, H, W)`` float32, pixels: ``(du, dv)`` such that pixel ``(u, v)`` of view i lands at
        ``(u + du, v + dv)`` in view j (NaN where view i sees nothing, depth ``inf``); and ``valid``
        ``(1, H, W)`` bool: view i sees a surface there, its point lies in front of camera j and
        within view j's pixel grid (its four nearest pixel centres inside), each of those four pixels
        sees a surface, their inverse depths spread by at most :data:`DEPTH_EDGE` (no outline
        between them), and view j's inverse depth interpolated bilinearly there agrees with the
        point's own within ``tolerance`` (relative): the point is not hidden in view j. With a batch,
        ``(B, 2, H, W)`` and ``(B, 1, H, W)``.

    Raises:
        KeyError: the sample has no ``depth`` (rendered without ``depth_output``).
        ValueError: a view index out of range, a tolerance that is not a positive number, or
            keys whose shapes do not fit together (each named).
    """
    if "depth" not in sample:
        raise KeyError("sample: no 'depth' key; render with the config field depth_output: true")
    depth, K, R, t, batched = _checked(sample)
    n_views = depth.shape[1]
    for name, view in (("i", i), ("j", j)):
        if isinstance(view, bool) or not isinstance(view, int) or not 0 <= view < n_views:
            raise ValueError(f"{name}: expected a view index in [0, {n_views}), got {view!r}")
    if isinstance(tolerance, bool) or not isinstance(tolerance, (int, float)) or not tolerance > 0:
        raise ValueError(f"tolerance: expected a positive number, got {tolerance!r}")
    flows, valid = depth_flow(depth[:, :, 0], K, R, t, i, j, tolerance)
    flows = flows.float()
    return (flows, valid) if batched else (flows[0], valid[0])


def _checked(sample: Mapping[str, Any]) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor, bool]:
    """``depth`` ``(B, V, 1, H, W)`` and ``K``, ``R`` ``(B, V, 3, 3)``, ``t`` ``(B, V, 3)`` (the shapes of
    ``sample.KEYS``), float64, with ``B = 1`` added for a single sample, and whether the sample was a batch."""
    depth = _float_tensor(sample, "depth")
    if depth.ndim not in (4, 5) or depth.shape[-3] != 1 or depth.shape[-2] < 2 or depth.shape[-1] < 2:
        raise ValueError(f"sample['depth']: expected (V, 1, H, W) or (B, V, 1, H, W) of at least 2 x 2 pixels, "
                         f"got {tuple(depth.shape)}")
    batched = depth.ndim == 5
    cameras = []
    for key in _CAMERAS:
        value = _float_tensor(sample, key.name)
        expected = (*depth.shape[:-3], *(int(axis) for axis in key.shape.strip("()").split(", ")[1:]))
        if tuple(value.shape) != expected:
            raise ValueError(f"sample[{key.name!r}]: expected shape {expected} to go with depth {tuple(depth.shape)}, "
                             f"got {tuple(value.shape)}")
        cameras.append(value if batched else value[None])
    return (depth if batched else depth[None]), *cameras, batched


_CAMERAS = tuple(next(key for key in KEYS if key.name == name) for name in "KRt")
"""The rows of ``sample.KEYS`` of the cameras: ``K``, ``R`` ``(V, 3, 3)`` and ``t`` ``(V, 3)``."""


def _float_tensor(sample: Mapping[str, Any], name: str) -> torch.Tensor:
    return float_tensor(sample, name, "depth, K, R, t").double()
