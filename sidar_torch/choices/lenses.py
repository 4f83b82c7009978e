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

__all__ = ["LENS_MODELS", "LensModel", "NO_LENS", "corner_coefficients", "corner_radius", "distorted_points", "scaled_lens", "undistorted_points"]

NO_LENS = "none"
"""``lens_model`` of a pinhole camera: nothing is distorted, nothing is drawn or paid."""

NEWTON_STEPS = 30
"""Newton steps inverting Brown-Conrady; within the config's bounds (:func:`radial_folds`) it converges
to 1e-12 in under 10."""


def _brown_distort(x: np.ndarray, lens: np.ndarray) -> np.ndarray:
    """OpenCV's distortion of undistorted normalised points ``x (..., 2)``."""
    k1, k2, p1, p2, k3 = lens
    u, v = x[..., 0], x[..., 1]
    r2 = u * u + v * v
    a = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
    return np.stack([u * a + 2 * p1 * u * v + p2 * (r2 + 2 * u * u), v * a + p1 * (r2 + 2 * v * v) + 2 * p2 * u * v], -1)


def _brown_undistort(xd: np.ndarray, lens: np.ndarray) -> np.ndarray:
    """The undistorted normalised points whose :func:`_brown_distort` is ``xd (..., 2)`` (Newton's method)."""
    k1, k2, p1, p2, k3 = lens
    x = xd.copy()
    for _ in range(NEWTON_STEPS):
        u, v = x[..., 0], x[..., 1]
        r2 = u * u + v * v
        a = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
        g = 2 * k1 + r2 * (4 * k2 + 6 * k3 * r2)  # d a / d u = g u, d a / d v = g v
        f = _brown_distort(x, lens) - xd
        j11 = a + g * u * u + 2 * p1 * v + 6 * p2 * u
        j12 = g * u * v + 2 * p1 * u + 2 * p2 * v
        j22 = a + g * v * v + 6 * p1 * v + 2 * p2 * u
        det = j11 * j22 - j12 * j12
        step = np.stack([(j22 * f[..., 0] - j12 * f[..., 1]) / det, (j11 * f[..., 1] - j12 * f[..., 0]) / det], -1)
        x -= step
        if np.abs(step).max(initial=0.0) < 1e-13:
            break
    return x


def _division_undistort(xd: np.ndarray, lens: np.ndarray) -> np.ndarray:
    return xd / (1 + lens[0] * np.sum(xd * xd, -1, keepdims=True))


def _division_distort(x: np.ndarray, lens: np.ndarray) -> np.ndarray:
    """The distorted points of undistorted ``x``: the root of ``lambda r_u r_d^2 - r_d + r_u = 0`` that is
    ``r_u`` at ``lambda = 0`` (written without the cancelling difference)."""
    r2 = np.sum(x * x, -1, keepdims=True)
    return 2 * x / (1 + np.sqrt(np.maximum(1 - 4 * lens[0] * r2, 0.0)))


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
        undistort: ``(x_d (..., 2), lens (5,))`` -> undistorted normalised points ``(..., 2)``.
        distort: ``(x_u (..., 2), lens (5,))`` -> distorted normalised points ``(..., 2)``.
        scale: ``(coefficients at the corner (5,), corner radius)`` -> the lens in normalised
            coordinates (:func:`scaled_lens`).
    """

    name: str
    fields: tuple[str | None, ...]
    undistort: Callable[[np.ndarray, np.ndarray], np.ndarray]
    distort: Callable[[np.ndarray, np.ndarray], np.ndarray]
    scale: Callable[[np.ndarray, float], np.ndarray]


LENS_MODELS = {row.name: row for row in (
    LensModel("brown_conrady", ("lens_k1", "lens_k2", "lens_p1", "lens_p2", "lens_k3"),
              _brown_undistort, _brown_distort, _brown_scale),
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


def undistorted_points(model: str, lens: np.ndarray, K: np.ndarray, pixels: np.ndarray) -> np.ndarray:
    """Where the distorted ``pixels (..., 2)`` (Kornia pixels) of a view lie in its undistorted
    (pinhole) image: ``(..., 2)`` float64 pixels, for the ``model``'s ``lens (5,)`` and ``K (3, 3)``."""
    return _through(LENS_MODELS[model].undistort, lens, K, pixels)


def distorted_points(model: str, lens: np.ndarray, K: np.ndarray, pixels: np.ndarray) -> np.ndarray:
    """Where the undistorted ``pixels (..., 2)`` of a view lie in its distorted image (the inverse of
    :func:`undistorted_points`), ``(..., 2)`` float64 pixels."""
    return _through(LENS_MODELS[model].distort, lens, K, pixels)


def _through(step: Callable[[np.ndarray, np.ndarray], np.ndarray], lens: np.ndarray, K: np.ndarray,
             pixels: np.ndarray) -> np.ndarray:
    f, c = np.array([K[0, 0], K[1, 1]]), K[:2, 2]
    skew = K[0, 1]
    y = (pixels[..., 1] - c[1]) / f[1]
    x = np.stack([(pixels[..., 0] - c[0] - skew * y) / f[0], y], -1)
    moved = step(x, np.asarray(lens, np.float64))
    return np.stack([f[0] * moved[..., 0] + skew * moved[..., 1] + c[0], f[1] * moved[..., 1] + c[1]], -1)


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
