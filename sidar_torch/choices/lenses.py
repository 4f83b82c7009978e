"""Lens distortion models as pure float64 math: the table of models (:data:`LENS_MODELS`), where a
distorted pixel comes from in the undistorted (pinhole) view and back, and the bound that keeps a
model invertible across a view.

Both the configuration (which checks the lens ranges) and the sample floor (which renders through a
lens, ``sidar_torch.sample.lens_views``) need these, so, like the rest of ``sidar_torch.choices``, this module
imports only NumPy.

Conventions. A lens acts on *normalised camera coordinates* ``x = K^-1 (u, v, 1)`` (Kornia pixels:
pixel (u, v) is column u, row v, the top-left pixel's centre is (0, 0)); ``K`` stays the pinhole
intrinsics. A lens is 5 float64 coefficients:

- ``brown_conrady``: OpenCV's ``(k1, k2, p1, p2, k3)`` (``cv2.undistort``, ``kornia.geometry.calibration``),
  mapping an undistorted point to its distorted one:
  ``x_d = x_u (1 + k1 r^2 + k2 r^4 + k3 r^6) + 2 p1 x_u y_u + p2 (r^2 + 2 x_u^2)``,
  ``y_d = y_u (1 + k1 r^2 + k2 r^4 + k3 r^6) + p1 (r^2 + 2 y_u^2) + 2 p2 x_u y_u``, ``r = |x_u|``;
- ``division``: Fitzgibbon's one parameter ``(lambda, 0, 0, 0, 0)`` (the model of ``homlib``'s solvers),
  mapping a distorted point to its undistorted one: ``x_u = x_d / (1 + lambda |x_d|^2)``.

Negative ``k1`` or ``lambda`` is barrel distortion (the corners pulled in), positive pincushion.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

__all__ = ["CHUNK", "LENS_MODELS", "Components", "LensModel", "NO_LENS", "NEWTON_TOLERANCE", "undistorted_grid", "corner_coefficients", "corner_radius", "distorted_points", "scaled_lens", "undistorted_points"]

NO_LENS = "none"
"""``lens_model`` of a pinhole camera: nothing is distorted, nothing is drawn or paid."""

NEWTON_STEPS = 30
"""Newton steps at most inverting Brown-Conrady; within the config's bounds (:func:`radial_folds`) it
converges in under 10 from the distorted point itself, in 2 from a start within a thousandth of a pixel."""

NEWTON_TOLERANCE = 1e-10
"""Newton's method stops where every point's residual ``|distort(x) - x_d|`` (normalised coordinates, each
axis) is under this: its error is at most the residual times the inverse Jacobian's norm, which the
config's bounds keep under 20 (:func:`radial_folds`' slope 0.05), so under 2e-6 pixels for any focal
length under 1000 pixels."""

CHUNK = 8192
"""Points evaluated together: arrays of this many float64 stay in the core's cache between the dozens of
operations of a step (a whole 384 x 512 view at once is about 3x slower)."""

Components = tuple[np.ndarray, np.ndarray]
"""A point set as its two coordinate arrays ``(u, v)``, each contiguous: the models work on them
(strided ``(..., 2)`` slices cost several times more per operation)."""


def _brown_distort(x: Components, lens: np.ndarray) -> Components:
    """OpenCV's distortion of undistorted normalised points ``x``."""
    return _brown_terms(*x, lens)[0]


def _brown_terms(u: np.ndarray, v: np.ndarray, lens: np.ndarray) -> tuple[Components, np.ndarray, np.ndarray]:
    """:func:`_brown_distort` of ``(u, v)``, with the squared radius ``r2`` and the radial factor ``a``
    (Newton's Jacobian reuses them)."""
    k1, k2, p1, p2, k3 = lens
    uu, vv, uv2 = u * u, v * v, 2 * u * v
    r2 = uu + vv
    a = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
    return (u * a + p1 * uv2 + p2 * (r2 + 2 * uu), v * a + p1 * (r2 + 2 * vv) + p2 * uv2), r2, a


def _brown_undistort(xd: Components, lens: np.ndarray, start: Components | None = None,
                     steps: int | None = None) -> Components:
    """The undistorted normalised points whose :func:`_brown_distort` is ``xd`` (Newton's method from
    ``start``, default ``xd`` itself, until every residual is under :data:`NEWTON_TOLERANCE`; or
    exactly ``steps`` steps, unchecked), in the dtype of ``xd`` and ``lens``."""
    k1, k2, p1, p2, k3 = lens
    u, v = (xd[0].copy(), xd[1].copy()) if start is None else (start[0].copy(), start[1].copy())
    for _ in range(NEWTON_STEPS if steps is None else steps):
        (fu, fv), r2, a = _brown_terms(u, v, lens)
        fu -= xd[0]
        fv -= xd[1]
        if steps is None and max(fu.max(initial=0.0), -fu.min(initial=0.0), fv.max(initial=0.0),
                                 -fv.min(initial=0.0)) < NEWTON_TOLERANCE:
            break
        g = 2 * k1 + r2 * (4 * k2 + 6 * k3 * r2)  # d a / d u = g u, d a / d v = g v
        gu, gv = g * u, g * v
        j11 = a + gu * u + 2 * p1 * v + 6 * p2 * u
        j12 = gu * v + 2 * p1 * u + 2 * p2 * v
        j22 = a + gv * v + 6 * p1 * v + 2 * p2 * u
        det = j11 * j22 - j12 * j12
        u -= (j22 * fu - j12 * fv) / det
        v -= (j11 * fv - j12 * fu) / det
    return u, v


def _division_undistort(xd: Components, lens: np.ndarray, start: Components | None = None,
                        steps: int | None = None) -> Components:
    s = 1 / (1 + lens[0] * (xd[0] * xd[0] + xd[1] * xd[1]))
    return xd[0] * s, xd[1] * s


def _division_distort(x: Components, lens: np.ndarray) -> Components:
    """The distorted points of undistorted ``x``: the root of ``lambda r_u r_d^2 - r_d + r_u = 0`` that is
    ``r_u`` at ``lambda = 0`` (written without the cancelling difference)."""
    r2 = x[0] * x[0] + x[1] * x[1]
    s = 2 / (1 + np.sqrt(np.maximum(1 - 4 * lens[0] * r2, 0.0)))
    return x[0] * s, x[1] * s


def _brown_scale(corner: np.ndarray, radius: float) -> np.ndarray:
    c1, c2, p1, p2, c3 = corner
    return np.array([c1 / radius**2, c2 / radius**4, p1 / radius, p2 / radius, c3 / radius**6])


def _division_scale(corner: np.ndarray, radius: float) -> np.ndarray:
    return np.array([corner[0] / radius**2, 0.0, 0.0, 0.0, 0.0])


@dataclass(frozen=True)
class LensModel:
    """One lens model: a row of :data:`LENS_MODELS`.

    Attributes:
        name: the ``lens_model`` config value.
        fields: the config fields (ranges) of its 5 coefficients, in the order of ``lens`` (None: always 0).
        undistort: ``(x_d, lens (5,), start, steps)`` -> the undistorted normalised points of ``x_d``; points
            as :data:`Components`, in their and ``lens``' dtype; ``start``: where an iterative model starts
            (None: ``x_d``), ``steps``: how many steps it takes (None: until :data:`NEWTON_TOLERANCE`);
            both unused by a closed form.
        distort: ``(x_u, lens (5,))`` -> the distorted normalised points of ``x_u`` (:data:`Components`).
        scale: ``(coefficients at the corner (5,), corner radius)`` -> the lens in normalised
            coordinates (:func:`scaled_lens`).
        iterative: ``undistort`` is Newton's method (a good ``start`` saves steps), not a closed form.
    """

    name: str
    fields: tuple[str | None, ...]
    undistort: Callable[[Components, np.ndarray, Components | None, int | None], Components]
    distort: Callable[[Components, np.ndarray], Components]
    scale: Callable[[np.ndarray, float], np.ndarray]
    iterative: bool = False


LENS_MODELS = {row.name: row for row in (
    LensModel("brown_conrady", ("lens_k1", "lens_k2", "lens_p1", "lens_p2", "lens_k3"),
              _brown_undistort, _brown_distort, _brown_scale, iterative=True),
    LensModel("division", ("lens_lambda", None, None, None, None), _division_undistort, _division_distort,
              _division_scale),
)}
"""The lens models by ``lens_model`` name (``"none"``, :data:`NO_LENS`, is no row: no lens)."""


def corner_radius(K: np.ndarray, image_size: tuple[int, int]) -> float:
    """The largest normalised radius ``|K^-1 (u, v, 1)|`` of the image's four outer corners
    (pixel edges, ``(-0.5, -0.5)`` to ``(W - 0.5, H - 0.5)``), for ``K (3, 3)`` float64."""
    h, w = image_size
    corners = np.array([[-0.5, -0.5, 1], [w - 0.5, -0.5, 1], [w - 0.5, h - 0.5, 1], [-0.5, h - 0.5, 1]])
    x = corners @ np.linalg.inv(K).T
    return float(np.linalg.norm(x[:, :2] / x[:, 2:], axis=1).max())


def scaled_lens(model: str, corner: np.ndarray, K: np.ndarray, image_size: tuple[int, int]) -> np.ndarray:
    """The ``(5,)`` float64 lens, in normalised coordinates, of a view with intrinsics ``K`` whose
    coefficients at the image's corner are ``corner`` (those the config ranges hold: ``k1 r_c^2``,
    ``k2 r_c^4``, ``p1 r_c``, ``p2 r_c``, ``k3 r_c^6`` and ``lambda r_c^2``, ``r_c`` the
    :func:`corner_radius`), so that a lens distorts every field of view alike."""
    return LENS_MODELS[model].scale(np.asarray(corner, np.float64), corner_radius(K, image_size))


def corner_coefficients(model: str, lens: np.ndarray, K: np.ndarray, image_size: tuple[int, int]) -> np.ndarray:
    """The inverse of :func:`scaled_lens`: the ``(5,)`` float64 coefficients at the image's corner (those
    the config ranges hold) of the ``model``'s ``lens (5,)`` for a view with intrinsics ``K``."""
    return LENS_MODELS[model].scale(np.asarray(lens, np.float64), 1 / corner_radius(K, image_size))


def undistorted_points(model: str, lens: np.ndarray, K: np.ndarray, pixels: np.ndarray,
                       start: np.ndarray | None = None) -> np.ndarray:
    """Where the distorted ``pixels (..., 2)`` (Kornia pixels) of a view lie in its undistorted
    (pinhole) image: ``(..., 2)`` float64 pixels, for the ``model``'s ``lens (5,)`` and ``K (3, 3)``.
    ``start``: ``(..., 2)`` pixels near the answer, where an iterative model (Brown-Conrady) starts
    (default ``pixels``); the answer is the same, to Newton's tolerance."""
    undistort, lens = LENS_MODELS[model].undistort, np.asarray(lens, np.float64)
    if start is None:
        return _chunked(lambda x: _pixels(K, undistort(_normalised(K, x), lens, None)), pixels)
    return _chunked(lambda x, s: _pixels(K, undistort(_normalised(K, x), lens, _normalised(K, s))), pixels, start)


def undistorted_grid(model: str, lens: np.ndarray, K: np.ndarray, image_size: tuple[int, int]) -> np.ndarray:
    """:func:`undistorted_points` of every pixel of a view of ``image_size (H, W)``, ``(H, W, 2)`` float64, for
    a closed-form model (not ``iterative``): the same numbers, with each row's and column's normalised
    coordinate computed once and broadcast (a third of the operations)."""
    row = LENS_MODELS[model]
    if row.iterative:
        raise ValueError(f"model: expected a closed-form lens model for undistorted_grid, got {model!r} (iterative: "
                         "use undistorted_points)")
    h, w = image_size
    y = ((np.arange(h, dtype=np.float64) - K[1, 2]) / K[1, 1])[:, None]
    x = (np.arange(w, dtype=np.float64)[None, :] - K[0, 2] - K[0, 1] * y) / K[0, 0]
    u, v = row.undistort((x, y), np.asarray(lens, np.float64), None)
    return _pixels(K, np.broadcast_arrays(u, v))


def distorted_points(model: str, lens: np.ndarray, K: np.ndarray, pixels: np.ndarray) -> np.ndarray:
    """Where the undistorted ``pixels (..., 2)`` of a view lie in its distorted image (the inverse of
    :func:`undistorted_points`), ``(..., 2)`` float64 pixels."""
    distort, lens = LENS_MODELS[model].distort, np.asarray(lens, np.float64)
    return _chunked(lambda x: _pixels(K, distort(_normalised(K, x), lens)), pixels)


def _chunked(step: Callable[..., np.ndarray], points: np.ndarray, *more: np.ndarray) -> np.ndarray:
    """``step`` (``(N, 2)`` pixels, and the same rows of each of ``more``, -> ``(N, 2)``) of ``points (..., 2)``,
    :data:`CHUNK` points at a time: ``(..., 2)`` float64."""
    flat = [np.asarray(a).reshape(-1, 2) for a in (points, *more)]
    out = np.empty((len(flat[0]), 2))
    for begin in range(0, len(out), CHUNK):
        out[begin:begin + CHUNK] = step(*(a[begin:begin + CHUNK] for a in flat))
    return out.reshape(*np.shape(points)[:-1], 2)


def _normalised(K: np.ndarray, pixels: np.ndarray) -> Components:
    """``pixels (..., 2)`` as normalised camera coordinates ``K^-1 (u, v, 1)``, contiguous components."""
    y = (pixels[..., 1] - K[1, 2]) / K[1, 1]
    return (pixels[..., 0] - K[0, 2] - K[0, 1] * y) / K[0, 0], np.ascontiguousarray(y)


def _pixels(K: np.ndarray, x: Components) -> np.ndarray:
    """Normalised points ``x`` as ``(..., 2)`` float64 pixels ``K (x, y, 1)``."""
    out = np.empty((*x[0].shape, 2))
    out[..., 0] = K[0, 0] * x[0] + K[0, 1] * x[1] + K[0, 2]
    out[..., 1] = K[1, 1] * x[1] + K[1, 2]
    return out


def radial_folds(model: str, corner: tuple[float, ...]) -> bool:
    """Whether the lens with coefficients ``corner`` at the image's corner (see :func:`scaled_lens`)
    folds before the corner: some distorted radius up to the corner's then has no undistorted source,
    or more than one. Radial terms only (the tangential ones, at most 1e-2, move a point by far less).

    Brown-Conrady: ``s (1 + c1 s^2 + c2 s^4 + c3 s^6)`` (``s`` the undistorted radius over the
    corner's) must rise, with slope above 0.05, until it reaches 1. Division: ``1 + lambda s^2``
    must stay above 0.1 and ``s / (1 + lambda s^2)`` rise (slope ``(1 - lambda s^2) / (1 + lambda
    s^2)^2`` above 0.05) for ``s`` up to 1.
    """
    s = np.linspace(0.0, 3.0, 3001)
    if model == "division":
        lam = corner[0]
        s = s[s <= 1.0]
        d = 1 + lam * s * s
        return bool(d.min() <= 0.1 or ((1 - lam * s * s) / d**2).min() <= 0.05)
    c1, c2, _, _, c3 = corner
    s2 = s * s
    value = s * (1 + s2 * (c1 + s2 * (c2 + s2 * c3)))
    slope = 1 + s2 * (3 * c1 + s2 * (5 * c2 + 7 * c3 * s2))
    reach = np.flatnonzero(value >= 1.0)
    if len(reach) == 0:
        return True
    return bool(slope[: reach[0] + 1].min() <= 0.05)
