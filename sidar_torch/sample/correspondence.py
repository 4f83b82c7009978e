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

from ..choices.outputs import OUTPUTS
from ..config import as_float, as_int
from .contract import KEYS, float_tensor
from .depth_flow import DEPTH_EDGE, DEPTH_TOLERANCE, depth_flow

__all__ = ["DEPTH_EDGE", "DEPTH_TOLERANCE", "FLOW_SOURCE", "flow"]

FLOW_SOURCE = OUTPUTS["flow_to_reference"].computed_from
"""The sample key :func:`flow` reads (the output the ``flow_to_reference`` row is computed from: ``depth``);
a batch that holds it can be given flow (``homography_pairs``)."""


def flow(sample: Mapping[str, Any], i: int, j: int, tolerance: float = DEPTH_TOLERANCE
         ) -> tuple[torch.Tensor, torch.Tensor]:
    """Where every pixel of view ``i`` lands in view ``j``, and whether view ``j`` sees it there.

    Args:
        sample: a sample dict with ``depth`` (``(V, 1, H, W)``, config ``depth_output``), ``K``, ``R``
            ``(V, 3, 3)`` and ``t`` ``(V, 3)``, or a batch of them (a leading ``B`` on each).
        i, j: the two views (``0 <= i, j < V``): integers of any kind (Python, NumPy, a 0-d tensor).
        tolerance: the relative depth disagreement (see :data:`DEPTH_TOLERANCE`) that still counts as
            the same surface, a positive number.

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
        ValueError: a view index out of range, a tolerance that is not a positive number, keys
            whose shapes do not fit together, or intrinsics ``K`` of view i or j that are not finite
            and invertible (each named).
    """
    if FLOW_SOURCE not in sample:
        raise KeyError(f"sample: no {FLOW_SOURCE!r} key; render with the config field {OUTPUTS[FLOW_SOURCE].switch}: true")
    depth, K, R, t, batched = _checked(sample)
    i, j = (_view_index(name, view, depth.shape[1]) for name, view in (("i", i), ("j", j)))
    tolerance = as_float("tolerance", tolerance, finite=False)
    if not tolerance > 0:
        raise ValueError(f"tolerance: expected a positive number, got {tolerance!r}")
    for name, view in (("i", i), ("j", j)):
        _check_intrinsics(K, view, name, batched)
    flows, valid = depth_flow(depth[:, :, 0], K, R, t, i, j, tolerance)
    flows = flows.float()
    return (flows, valid) if batched else (flows[0], valid[0])


def _view_index(name: str, value: Any, n_views: int) -> int:
    """``value`` as a view index in ``[0, n_views)`` (any integer scalar, ``config.as_int``).

    Raises:
        ValueError: not an integer (a bool included) or out of range, naming ``name``.
    """
    expected = f"{name}: expected a view index in [0, {n_views})"
    try:
        view = as_int(name, value)
    except ValueError:
        raise ValueError(f"{expected}, got {value!r}") from None
    if not 0 <= view < n_views:
        raise ValueError(f"{expected}, got {value!r}")
    return view


def _check_intrinsics(K: torch.Tensor, view: int, name: str, batched: bool) -> None:
    """Refuse intrinsics of ``view`` (``K`` ``(B, V, 3, 3)`` float64) that are not finite or not
    invertible (rank below 3, ``torch.linalg.matrix_rank``'s tolerance): view ``i``'s pixels are lifted
    through ``K^-1``, view ``j``'s projected through ``K``.

    Raises:
        ValueError: naming the view (``name`` and index), the batch item if ``batched``, and the matrix.
    """
    k = K[:, view]
    finite = torch.isfinite(k).all(dim=(1, 2))
    ranks = torch.linalg.matrix_rank(torch.where(finite[:, None, None], k, torch.eye(3, dtype=k.dtype)))
    for item in torch.nonzero(~finite | (ranks < 3)).flatten().tolist():
        where = f"[{item}, {view}]" if batched else f"[{view}]"
        problem = "not finite" if not finite[item] else f"singular (rank {int(ranks[item])})"
        raise ValueError(f"sample['K']{where}: expected the invertible 3 x 3 intrinsics of view {name}={view}, got "
                         f"{k[item].tolist()}, {problem}")


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
