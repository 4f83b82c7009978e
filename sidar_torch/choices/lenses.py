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

import functools
import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

__all__ = ["CHUNK", "LENS_MODELS", "Components", "LensModel", "NO_LENS", "NEWTON_TOLERANCE", "undistorted_grid", "corner_coefficients", "corner_radius", "distorted_points", "LEAST_SLOPE", "lens_folds", "scaled_lens", "undistorted_points"]

NO_LENS = "none"
"""``lens_model`` of a pinhole camera: nothing is distorted, nothing is drawn or paid."""

NEWTON_STEPS = 40
"""Newton steps at most inverting Brown-Conrady to :data:`NEWTON_TOLERANCE` (:func:`_brown_undistort`, safeguarded:
a step is shortened until it lowers the residual and stays where the lens is one to one). From the GL pass's start
``x_d / a(|x_d|^2)`` a lens that does not fold (:func:`lens_folds`) takes at most 8 over a 768 x 1024 view (3,200
random lenses of the config's bounds, 1,400 of them strong pincushions with negative ``k3``; the default ranges'
take 2-3); undamped steps from ``x_d`` itself, before, did not converge for about 1 % of them. A point still above
the tolerance after these is a ``ValueError``, never an answer."""

NEWTON_TOLERANCE = 1e-10
"""Newton's method stops where every point's residual ``|distort(x) - x_d|`` (normalised coordinates, Euclidean
norm) is under this: its error is at most the residual times the inverse Jacobian's norm, which the
config keeps under 20 (:func:`lens_folds`: :data:`LEAST_SLOPE`), so under 2e-6 pixels for any focal
length under 1000 pixels."""

_BACKTRACKS = 30
"""Halvings of a Newton step at most before a point stays where it is for that step (:func:`_brown_undistort`)."""

_ARMIJO = 1e-4
"""The share of the decrease its linear model promises that a (shortened) Newton step must give the squared
residual to be taken (Armijo's rule)."""

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


def _brown_start(xd: Components, lens: np.ndarray) -> Components:
    """Where Newton's method starts inverting Brown-Conrady at distorted points ``xd``: ``x_d / a(|x_d|^2)``,
    ``a`` the radial factor (the GL pass's start, ``render/shaders/resample.frag``)."""
    k1, k2, _, _, k3 = lens
    d2 = xd[0] * xd[0] + xd[1] * xd[1]
    a = 1 + d2 * (k1 + d2 * (k2 + d2 * k3))
    return xd[0] / a, xd[1] / a


def _newton_step(u: np.ndarray, v: np.ndarray, fu: np.ndarray, fv: np.ndarray, r2: np.ndarray, a: np.ndarray,
                 lens: np.ndarray) -> Components:
    """Newton's step ``J^-1 f`` at undistorted points ``(u, v)`` with residuals ``(fu, fv)`` (distorted minus
    target), squared radius ``r2`` and radial factor ``a`` (:func:`_brown_terms`): subtract it from ``(u, v)``."""
    k1, k2, p1, p2, k3 = lens
    g = 2 * k1 + r2 * (4 * k2 + 6 * k3 * r2)  # d a / d u = g u, d a / d v = g v
    gu, gv = g * u, g * v
    j11 = a + gu * u + 2 * p1 * v + 6 * p2 * u
    j12 = gu * v + 2 * p1 * u + 2 * p2 * v
    j22 = a + gv * v + 6 * p1 * v + 2 * p2 * u
    det = j11 * j22 - j12 * j12
    return (j22 * fu - j12 * fv) / det, (j11 * fv - j12 * fu) / det


def _brown_undistort(xd: Components, lens: np.ndarray, start: Components | None = None,
                     steps: int | None = None) -> Components:
    """The undistorted normalised points whose :func:`_brown_distort` is ``xd``, in the dtype of ``xd`` and
    ``lens``, by Newton's method from ``start`` (default :func:`_brown_start`, the GL pass's).

    With ``steps``: exactly that many plain Newton steps, unchecked, ``lens`` ``(5,)`` or ``(5, ...)``
    broadcasting against the points (what the GL pass computes: ``render.resample``). Without (``lens (5,)``,
    points 1-D): safeguarded until every residual is under :data:`NEWTON_TOLERANCE`. The lens's Jacobian is
    symmetric (see :func:`lens_folds`), so within the disk ``|x| < R`` where it stays positive definite
    (:func:`_one_to_one_radius`) the lens is one to one and has at most one answer, the right one: each step is
    halved (at most :data:`_BACKTRACKS` times) until it stays in that disk and lowers the squared residual by
    Armijo's rule (Newton's direction always descends it, and is taken whole near the answer), a start outside
    the disk is moved to its centre. So the residual falls at every step and cannot settle on another root
    beyond a fold.

    Raises:
        ValueError: a point whose residual is not under :data:`NEWTON_TOLERANCE` after :data:`NEWTON_STEPS`
            steps (a lens that folds the view before these points), naming the lens and the worst residual.
    """
    u, v = _brown_start(xd, lens) if start is None else (start[0].copy(), start[1].copy())
    if steps is not None:
        for _ in range(steps):
            (fu, fv), r2, a = _brown_terms(u, v, lens)
            du, dv = _newton_step(u, v, fu - xd[0], fv - xd[1], r2, a, lens)
            u -= du
            v -= dv
        return u, v
    reach = _one_to_one_radius(tuple(float(c) for c in lens), _radius_scale(xd))
    outside = ~(u * u + v * v < reach * reach)  # NaN starts too
    u[outside] = 0.0
    v[outside] = 0.0
    state = _trial(xd, lens, reach, u, v)[:-1]  # (u, v, fu, fv, r2, a, squared residual)
    for _ in range(NEWTON_STEPS):
        if state[-1].max(initial=0.0) < NEWTON_TOLERANCE**2:  # NaN is not under it
            break
        state = _safeguarded_step(xd, lens, reach, state)
    worst = math.sqrt(state[-1].max(initial=0.0))
    if worst < NEWTON_TOLERANCE:
        return state[0], state[1]
    raise ValueError(f"lens: brown_conrady {np.asarray(lens).tolist()} (normalised coordinates) left a residual of "
                     f"{worst:.3g} after {NEWTON_STEPS} Newton steps, over NEWTON_TOLERANCE {NEWTON_TOLERANCE:g}: a lens "
                     "that folds the view before these points (choices.lenses.lens_folds)")


def _safeguarded_step(xd: Components, lens: np.ndarray, reach: float, state: tuple[np.ndarray, ...]
                      ) -> tuple[np.ndarray, ...]:
    """One step of :func:`_brown_undistort`'s safeguarded Newton from ``state`` (``(u, v, fu, fv, r2, a, squared)``:
    the points, residuals, squared radius, radial factor and squared residual, as :func:`_trial` returns them):
    Newton's step, halved for the points it does not suit (:func:`_trial`) at most :data:`_BACKTRACKS` times
    (those no halving suits stay where they are); the new state."""
    u, v, fu, fv, r2, a, squared = state
    du, dv = _newton_step(u, v, fu, fv, r2, a, lens)
    *step, taken = _trial(xd, lens, reach, u - du, v - dv, squared)
    rows = np.flatnonzero(~taken)
    for halvings in range(1, _BACKTRACKS + 1):
        if not len(rows):
            break
        t = 0.5**halvings
        *shorter, taken = _trial((xd[0][rows], xd[1][rows]), lens, reach, u[rows] - t * du[rows],
                                 v[rows] - t * dv[rows], squared[rows], t)
        for whole, part in zip(step, shorter):
            whole[rows] = part
        rows = rows[~taken]
    for whole, now in zip(step, state):
        whole[rows] = now[rows]
    return tuple(step)


def _trial(xd: Components, lens: np.ndarray, reach: float, u: np.ndarray, v: np.ndarray,
           squared: np.ndarray | None = None, t: float = 1.0) -> tuple[np.ndarray, ...]:
    """Brown-Conrady ``lens`` at points ``(u, v)`` against the targets ``xd``: ``(u, v, fu, fv, r2, a, squared,
    taken)``, the residuals, squared radius and radial factor (:func:`_brown_terms`), the squared residual and
    whether each point takes this (shortened) Newton step of :func:`_brown_undistort` from points whose squared
    residual was ``squared``, ``t`` its share of the whole step: inside ``|x| < reach``, and the squared residual
    lowered by Armijo's rule or its norm under :data:`NEWTON_TOLERANCE` (None: ``taken`` is None)."""
    (fu, fv), r2, a = _brown_terms(u, v, lens)
    fu -= xd[0]
    fv -= xd[1]
    now = fu * fu + fv * fv
    taken = None if squared is None else (r2 < reach * reach) & (
        (now <= (1 - 2 * _ARMIJO * t) * squared) | (now < NEWTON_TOLERANCE**2))
    return u, v, fu, fv, r2, a, now, taken


def _radius_scale(xd: Components) -> float:
    """The least power of 2 at or above the largest radius of the distorted points ``xd`` (at least 2^-20): the
    scale of :func:`_one_to_one_radius`, rounded so that the chunks of a view share one (cached) answer."""
    largest = float(np.sqrt(np.max(xd[0] * xd[0] + xd[1] * xd[1], initial=0.0)))
    return 2.0 ** max(math.ceil(math.log2(largest)) if largest > 0 else -20, -20)


@functools.lru_cache(maxsize=64)
def _one_to_one_radius(lens: tuple[float, ...], scale: float) -> float:
    """The radius (normalised coordinates) of the disk around the centre where Brown-Conrady ``lens`` (5 floats)
    keeps a positive definite Jacobian, looked for in steps of ``scale / 1000`` up to ``3 scale`` (``scale``: at
    least the points' largest radius): the last radius looked at before the least eigenvalue (over the angle,
    :func:`_fold_profile`) falls to 0, or ``3 scale`` where it never does. Inside it the lens is one to one (the
    gradient of a strictly convex function), and it holds the answer of every point of an image whose lens does
    not fold (:func:`lens_folds` asks for an eigenvalue above :data:`LEAST_SLOPE` out to where the image's corner
    is reached)."""
    least_eigenvalue, _ = _fold_profile(_brown_scale(np.array(lens), 1 / scale), _FOLD_RADII)
    folded = np.flatnonzero(least_eigenvalue <= 0)
    return scale * float(_FOLD_RADII[folded[0] - 1] if len(folded) else _FOLD_RADII[-1])


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
            (None: the GL pass's start), ``steps``: how many plain steps it takes (None: safeguarded until
            :data:`NEWTON_TOLERANCE`, or a ``ValueError``); both unused by a closed form.
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


def undistorted_points(model: str, lens: np.ndarray, K: np.ndarray, pixels: np.ndarray) -> np.ndarray:
    """Where the distorted ``pixels (..., 2)`` (Kornia pixels) of a view lie in its undistorted
    (pinhole) image: ``(..., 2)`` float64 pixels, for the ``model``'s ``lens (5,)`` and ``K (3, 3)``. An iterative
    model (Brown-Conrady) ends within :data:`NEWTON_TOLERANCE` at every point or raises.

    Raises:
        ValueError: an iterative model that does not converge at some point (a lens that folds the view before
            it, :func:`lens_folds`), naming the lens and the worst residual.
    """
    undistort, lens = LENS_MODELS[model].undistort, np.asarray(lens, np.float64)
    return _chunked(lambda x: _pixels(K, undistort(_normalised(K, x), lens, None, None)), pixels)


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


def _chunked(step: Callable[[np.ndarray], np.ndarray], points: np.ndarray) -> np.ndarray:
    """``step`` (``(N, 2)`` pixels -> ``(N, 2)``) of ``points (..., 2)``, :data:`CHUNK` points at a time:
    ``(..., 2)`` float64."""
    flat = np.asarray(points).reshape(-1, 2)
    out = np.empty((len(flat), 2))
    for begin in range(0, len(out), CHUNK):
        out[begin:begin + CHUNK] = step(flat[begin:begin + CHUNK])
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


LEAST_SLOPE = 0.05
"""The least slope a lens that does not fold keeps over the image (:func:`lens_folds`): its inverse's Jacobian
then has a norm under 20, so Newton's method is well conditioned and a residual moves a source little."""

_FOLD_RADII = np.linspace(0.0, 3.0, 3001)
"""Radii, over the corner's, at which :func:`lens_folds` looks (steps of 1e-3; a lens reaching the corner only
beyond 3 folds)."""


def lens_folds(model: str, corners: np.ndarray) -> np.ndarray:
    """Whether each lens with coefficients ``corners (..., 5)`` (float64, at the image's corner: see
    :func:`scaled_lens`) folds the view over the image: some pixel then has no source in the undistorted view,
    or more than one, or one so ill-conditioned that Newton's method may not settle on it. ``(...)`` bool. The
    one definition of folding: the config refuses ranges holding such a lens, the renderer
    (``render.resample.LensResampling.of``) and the export reader refuse such a lens. The exact inverse
    (:func:`undistorted_points`) converges for every lens that does not fold; the renderer's undamped Newton steps
    do near the edge of barrel folding (``tests/render/test_lens.py``), not for about 1 % of strong pincushions
    with negative ``k3`` (``render.resample._border_sources`` then refuses them).

    In coordinates over the corner's radius (the image inside the unit disk) every lens is a map ``D`` of the
    plane, and a lens does not fold when it stays :data:`LEAST_SLOPE` away from folding out to the corner:

    - ``brown_conrady`` (``D`` undistorted to distorted, ``D(s) = s a(|s|^2) + |s|^2 p + 2 (p . s) s``, ``p = (p2,
      p1)``): ``D``'s Jacobian is symmetric (``D`` is a gradient), ``[[g + 6 |s| p_r, 2 |s| p_t], [2 |s| p_t, a +
      2 |s| p_r]]`` in the frame of ``s`` (``g = d(|s| a)/d|s|`` the radial slope, ``p_r, p_t`` ``p``'s components
      along and across ``s``). Its smallest eigenvalue must exceed :data:`LEAST_SLOPE` over the disk ``|s| <= rho``,
      ``rho`` the least radius whose circle ``D`` maps outside the unit disk. Then ``D`` is strongly monotone on
      that (convex) disk, so one to one with an inverse Jacobian under ``1 / LEAST_SLOPE``, and its image holds
      the unit disk (``D(0) = 0``): every pixel of the image has one source. Both the eigenvalue and ``|D|``
      depend on ``s`` only through ``|s|`` and its angle to ``p``; their least values over the angle are taken in
      closed form, so the check runs over :data:`_FOLD_RADII` alone. Without tangential terms the eigenvalues are
      ``g`` and ``a``, and this is: ``|s| a`` rises with slope above :data:`LEAST_SLOPE` until it reaches 1.
    - ``division`` (``D`` distorted to undistorted, ``s / (1 + lambda |s|^2)``, in closed form): ``1 + lambda
      |s|^2`` must stay above 0.1 and the radial slope ``(1 - lambda |s|^2) / (1 + lambda |s|^2)^2`` above
      :data:`LEAST_SLOPE` for ``|s|`` up to 1.

    A lens is worse the lower its radial coefficients (every eigenvalue and ``|D|`` fall with them) and the larger
    ``|p|``, so the worst lens of a box of coefficients is one of its corners
    (``tests/config/test_config_lens.py`` measures it).
    """
    corners = np.asarray(corners, np.float64)
    if model == "division":
        c1 = corners[..., 0, None]
        s2 = np.square(_FOLD_RADII[_FOLD_RADII <= 1.0])
        d = 1 + c1 * s2
        return (d.min(axis=-1) <= 0.1) | (((1 - c1 * s2) / d**2).min(axis=-1) <= LEAST_SLOPE)
    least_eigenvalue, radius = _fold_profile(corners, _FOLD_RADII)
    reached = radius >= 1.0
    before = np.cumsum(reached, axis=-1) - reached == 0  # radii up to the first that reaches the unit circle
    return ~reached.any(axis=-1) | (before & (least_eigenvalue <= LEAST_SLOPE)).any(axis=-1)


def _fold_profile(corners: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For Brown-Conrady lenses ``corners (..., 5)`` (coefficients at a reference radius) and radii ``s (S,)`` over
    that radius: the least eigenvalue of the Jacobian over the circle of each radius, and the least radius
    ``|D|`` the circle is mapped to, each ``(..., S)`` float64, in closed form (:func:`lens_folds`)."""
    c1, c2, p1, p2, c3 = (corners[..., i, None] for i in range(5))  # (..., 1) each, against radii on the last axis
    s2 = s * s
    a = 1 + s2 * (c1 + s2 * (c2 + s2 * c3))  # the radial factor
    g = 1 + s2 * (3 * c1 + s2 * (5 * c2 + 7 * c3 * s2))  # d(s a) / ds
    e = 2 * s * np.hypot(p1, p2)  # the Jacobian's tangential part is e times [[3 cos, sin], [sin, cos]]
    half = (g - a) / 2
    # At the cosine c of the angle between s and p the smallest eigenvalue is (g + a) / 2 + 2 e c - sqrt(half^2 +
    # e^2 + 2 half e c), convex in c: least at its stationary point -(3 half^2 / 4 + e^2) / (2 half e) when that
    # lies in [-1, 1], else at c = -1 (p against s).
    stationary = 0.75 * half * half + e * e
    inside = stationary < 2 * half * e
    c = np.where(inside, -stationary / np.where(inside, 2 * half * e, 1.0), -1.0)
    least_eigenvalue = (g + a) / 2 + 2 * e * c - np.sqrt(np.maximum(half * half + e * e + 2 * half * e * c, 0.0))
    # |D|^2 / s^2 = a^2 + 3 a e c + 2 e^2 c^2 + e^2 / 4, least at c = -3 a / (4 e) within [-1, 1].
    c = np.clip(-3 * a / np.where(e > 0, 4 * e, 1.0), -1.0, 1.0) * (e > 0)
    radius = s * np.sqrt(np.maximum(a * a + 3 * a * e * c + 2 * e * e * c * c + e * e / 4, 0.0))
    return least_eigenvalue, radius
