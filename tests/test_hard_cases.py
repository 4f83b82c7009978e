"""Hard cases for the homographies, at the geometry and sampler level (no rendering).

Every homography is checked where it matters: at painting points that both views see (in front
of both cameras, inside both images), in pixels of the target view, against where the two
cameras project the same 3-D point (``geometry.project``), and against the analytic
plane-induced homography ``K_j (R - t n^T / d) K_i^{-1}``. It is computed the way the dataset
computes it (``sample.sequence_homographies`` on a ``SceneSequence``: Kornia's DLT on four
projected plane points, det = 1).

Targets and what was measured (``python tests/test_hard_cases.py`` prints the figures):

* float64: at most ``TARGET_PX`` = 1e-6 px, for every case below and every sampled config. A
  pair whose local magnification ``M`` (view-j pixels per view-i pixel) is so large that
  ``eps * M * |x_i|`` approaches 1e-6 px is ill-conditioned, not wrong: rounding the view-i pixel
  coordinate to float64 already moves its image by that much, so no homography, not even the
  exact one, can do better. There the bound is relative: ``ILL_CONDITIONED * floor`` with
  ``floor = eps * (M (|x_i| + 1) + |x_j| + 1)`` (see :func:`floor_px`).
* sign: with det = 1, the third homogeneous coordinate of ``H[i, j] (u, v, 1)`` is positive at
  every point both views see, and proportional to ``depth_j / depth_i`` of the 3-D point.
* float32 (what the dataset hands out): rounding the entries moves points by at most the
  first-order bound of rounding each entry once (:func:`float32_bound_px`), and by at most
  ``F32_TYPICAL_PX`` for the ``misaligned`` preset.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sidar_torch import geometry, load_config
from sidar_torch.sample import sequence_homographies
from sidar_torch.scene import Camera, Material, SceneSequence, ViewScene, sample_sequence

TARGET_PX = 1e-6
"""float64 target: DLT against projection and against the analytic homography, in pixels."""

ILL_CONDITIONED = 64
"""Allowed multiple of the float64 resolution floor where that floor approaches ``TARGET_PX``
(measured: at most 32 wherever the floor exceeds 1e-9 px)."""

DET_TOL = 1e-9
EPS64 = float(np.finfo(np.float64).eps)
EPS32 = 2.0**-24  # float32 unit round-off

F32_TYPICAL_PX = 1e-3
"""float32 round-off bound for the ``misaligned`` preset at 384 x 512 (measured over 20 sequences:
1.4e-4 px at shared points, 3.6e-4 px at image corners, 1.2e-4 for ``|H32 H32' - I|``)."""


# --- cameras and homographies, built with the package's own functions ----------------------

def camera(tilt_deg: float, azimuth_deg: float, distance: float, fov_deg: float, size) -> Camera:
    """A camera aimed at the painting's centre from ``distance`` (painting units), its axis
    ``tilt_deg`` from the painting's normal, seen from ``azimuth_deg`` around it."""
    a, b = math.radians(tilt_deg), math.radians(azimuth_deg)
    position = distance * np.array([math.sin(a) * math.cos(b), math.sin(a) * math.sin(b), math.cos(a)])
    return Camera(geometry.intrinsics_from_fov(fov_deg, size), *geometry.look_at(position))


def reference(size, distance: float) -> Camera:
    return Camera(*geometry.reference_camera(size, distance))


def sequence(cameras, size) -> SceneSequence:
    """A scene with these cameras and nothing else (no lights, no occluders)."""
    plane = Material(np.ones(4), 0.0, 1.0)
    return SceneSequence(tuple(size), tuple(ViewScene(c, (), (), plane, 0.1) for c in cameras))


def homographies(cameras, size) -> tuple[np.ndarray, np.ndarray, float]:
    """``(H_dlt, H_analytic, dataset_error)``: the dataset's float64 homographies, the analytic
    plane-induced ones, and the dataset's own ``homography_error``."""
    seq = sequence(cameras, size)
    H, error = sequence_homographies(seq)
    return H.numpy(), geometry.plane_induced_homographies(*seq.cameras()), error


# --- the points that matter -----------------------------------------------------------------

def pixel_grid(size, n: int) -> np.ndarray:
    h, w = size
    u, v = np.meshgrid(np.linspace(-0.5, w - 0.5, n), np.linspace(-0.5, h - 0.5, n))
    return np.stack([u.ravel(), v.ravel()], 1)


def cast(cam: Camera, pixels: np.ndarray) -> np.ndarray:
    """Plane points ``(N', 3)`` seen at ``pixels`` (rays that meet the plane z = 0 in front)."""
    rays = np.concatenate([pixels, np.ones((len(pixels), 1))], 1) @ np.linalg.inv(cam.K).T @ cam.R
    centre = cam.position
    with np.errstate(divide="ignore", invalid="ignore"):
        s = -centre[2] / rays[:, 2]
    front = s > 0
    points = centre + s[front, None] * rays[front]
    points[:, 2] = 0.0
    return points


def depth(cam: Camera, points: np.ndarray) -> np.ndarray:
    return points @ cam.R[2] + cam.t[2]


def inside(size, x: np.ndarray) -> np.ndarray:
    h, w = size
    return (x[:, 0] >= -0.5) & (x[:, 0] <= w - 0.5) & (x[:, 1] >= -0.5) & (x[:, 1] <= h - 0.5)


def shared_points(cams, size, i: int, j: int, n: int = 15):
    """Painting points that views ``i`` and ``j`` both see: ``(X (N, 3), x_i (N, 2), x_j (N, 2))``.

    Candidates: an ``n x n`` grid over the painting, and the painting points seen by an
    ``n x n`` pixel grid of either view (so a view that sees a sliver of the painting still
    gets ``~n^2`` points). Kept: on the painting, in front of both cameras, inside both images.
    """
    pw, ph = geometry.plane_size(size)
    gx, gy = np.meshgrid(np.linspace(-pw / 2, pw / 2, n), np.linspace(-ph / 2, ph / 2, n))
    X = np.concatenate([np.stack([gx.ravel(), gy.ravel(), np.zeros(n * n)], 1),
                        cast(cams[i], pixel_grid(size, n)), cast(cams[j], pixel_grid(size, n))])
    X = X[(np.abs(X[:, 0]) <= pw / 2) & (np.abs(X[:, 1]) <= ph / 2)]
    X = X[(depth(cams[i], X) > 0) & (depth(cams[j], X) > 0)]
    xi = geometry.project(cams[i].K, cams[i].R, cams[i].t, X)
    xj = geometry.project(cams[j].K, cams[j].R, cams[j].t, X)
    keep = inside(size, xi) & inside(size, xj)
    return X[keep], xi[keep], xj[keep]


def transfer(H: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``x (N, 2)`` mapped by ``H (3, 3)``: pixels ``(N, 2)`` and the third coordinate ``(N,)``."""
    y = np.concatenate([x, np.ones((len(x), 1))], 1) @ H.T
    return y[:, :2] / y[:, 2:], y[:, 2]


def magnification(H: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Largest singular value of the Jacobian of ``x -> H x`` at each point ``(N,)``: how many
    view-j pixels one view-i pixel becomes."""
    y, w = transfer(H, x)
    J = (H[None, :2, :2] - y[:, :, None] * H[None, 2:3, :2]) / w[:, None, None]
    return np.linalg.svd(J, compute_uv=False)[:, 0]


def floor_px(H: np.ndarray, xi: np.ndarray, xj: np.ndarray) -> np.ndarray:
    """float64 resolution at each point ``(N,)``, px of view j: the error an exact homography
    makes from rounding ``x_i`` (magnified ``M`` times) and ``x_j`` to float64."""
    return EPS64 * (magnification(H, xi) * (np.abs(xi).max(1) + 1) + np.abs(xj).max(1) + 1)


def check_pairs(cams, size, relative: bool = False, n: int = 15) -> dict:
    """Check every ordered pair of ``cams`` and return the worst figures.

    Asserts: finite, det = 1, ``H[i, i] = I``; at every point both views see, in both directions
    of every pair (so ``H[j, i] = H[i, j]^-1`` where it matters): the third coordinate is > 0 and
    proportional to ``depth_j / depth_i``, and the DLT agrees with projection and with the analytic
    homography within ``TARGET_PX`` (or, if ``relative``, ``max(TARGET_PX, ILL_CONDITIONED * floor)``);
    the dataset's ``homography_error`` is within ``TARGET_PX`` (unless ``relative``).
    """
    H, H_true, dataset_error = homographies(cams, size)
    V = len(cams)
    assert np.isfinite(H).all()
    # np.linalg.det itself is only good to ~eps * cond(H), which matters for huge magnifications.
    det_tol = np.maximum(DET_TOL, 16 * EPS64 * np.linalg.cond(H)) if relative else DET_TOL
    assert (np.abs(np.linalg.det(H) - 1) <= det_tol).all(), np.linalg.det(H)
    worst = {"projection": 0.0, "analytic": 0.0, "floor": 0.0, "points": 0, "dataset": dataset_error}
    for i in range(V):
        np.testing.assert_array_equal(H[i, i], np.eye(3))
        for j in range(V):
            if i == j:
                continue
            X, xi, xj = shared_points(cams, size, i, j, n)
            assert len(X) > 0, "both cameras aim at the painting's centre, so both see it"
            y, w = transfer(H[i, j], xi)
            y_true, _ = transfer(H_true[i, j], xi)
            # Sign and scale: w = c * depth_j / depth_i with one constant c > 0 for every point.
            ratio = w * depth(cams[i], X) / depth(cams[j], X)
            assert (w > 0).all(), f"H[{i}, {j}] sends a shared point behind camera {j}"
            np.testing.assert_allclose(ratio, ratio[0], rtol=1e-6 if relative else 1e-9)
            error = np.linalg.norm(y - xj, axis=1)
            analytic = np.linalg.norm(y - y_true, axis=1)
            floor = floor_px(H_true[i, j], xi, xj)
            allowed = np.maximum(TARGET_PX, ILL_CONDITIONED * floor) if relative else TARGET_PX
            assert (error <= allowed).all(), (i, j, error.max(), floor.max())
            assert (analytic <= allowed).all(), (i, j, analytic.max(), floor.max())
            worst["projection"] = max(worst["projection"], float(error.max()))
            worst["analytic"] = max(worst["analytic"], float(analytic.max()))
            worst["floor"] = max(worst["floor"], float(floor.max()))
            worst["points"] += len(X)
    if not relative:  # the dataset's own figure, on a 17 x 17 lattice of shared points
        assert dataset_error <= TARGET_PX
    return worst


def coverage(cam: Camera, size) -> float:
    """Fraction of the view's area the painting covers (painting in front of the camera)."""
    corners = geometry.plane_corners(size)
    assert (depth(cam, corners) > 0).all()
    x = geometry.project(cam.K, cam.R, cam.t, corners)
    area = 0.5 * abs(np.dot(x[:, 0], np.roll(x[:, 1], -1)) - np.dot(x[:, 1], np.roll(x[:, 0], -1)))
    return area / (size[0] * size[1])


SIZE = (384, 512)


@pytest.fixture(autouse=True, scope="module")
def one_torch_thread():
    """The linear algebra here is on 3 x 3 and 8 x 9 matrices: torch's intra-op threads only add
    synchronisation, which costs ~10 ms per call on a busy 2-core machine (0.01 ms with one)."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


# --- the hard cases, one test each -------------------------------------------------------------

@pytest.mark.parametrize("size", [SIZE, (512, 4096)])
def test_grazing_cameras_tilted_85_degrees(size):
    for fov in (10, 60, 120):
        for distance in (0.05, 1.0, 100.0):
            cams = [reference(size, 0.9), camera(85, 30, distance, fov, size), camera(85, 210, 1.0, 60, size)]
            check_pairs(cams, size)


def test_narrow_and_wide_fields_of_view():
    cams = [reference(SIZE, 0.9), camera(40, 0, 1.0, 10, SIZE), camera(40, 120, 1.0, 120, SIZE),
            camera(0, 0, 0.5, 120, SIZE), camera(70, 250, 3.0, 10, SIZE)]
    check_pairs(cams, SIZE)


def test_cameras_very_close_to_and_very_far_from_the_painting():
    for size in (SIZE, (2048, 2048)):
        cams = [reference(size, 0.05), camera(60, 10, 0.05, 60, size), camera(30, 100, 100.0, 10, size),
                camera(0, 0, 100.0, 120, size), camera(85, 300, 0.05, 120, size)]
        check_pairs(cams, size)


def test_painting_covering_under_one_percent_of_a_view():
    far = camera(50, 45, 30.0, 60, SIZE)
    assert coverage(far, SIZE) < 0.01
    tiny = camera(0, 0, 100.0, 120, SIZE)
    assert coverage(tiny, SIZE) < 1e-4
    check_pairs([reference(SIZE, 0.9), far, tiny, camera(30, 200, 0.7, 90, SIZE)], SIZE)


@pytest.mark.parametrize("size", [(64, 512), (512, 64), (512, 4096), (4096, 512)])
def test_extreme_aspect_ratios(size):
    cams = [reference(size, 0.8), camera(60, 0, 0.8, 90, size), camera(60, 90, 0.8, 90, size),
            camera(85, 180, 2.0, 30, size)]
    check_pairs(cams, size)


@pytest.mark.parametrize("size", [(1, 1), (1, 2), (2, 1), (3, 5), (5, 3), (1, 8), (131, 257)])
def test_tiny_and_odd_output_sizes(size):
    cams = [reference(size, 0.9), camera(45, 30, 1.0, 60, size), camera(80, 200, 0.3, 110, size)]
    check_pairs(cams, size)


def test_far_and_close_cameras_together():
    """A grazing camera 2000 times farther than the nearest one: the fit square sized by the
    nearest camera alone spanned 0.03 x 0.4 px in the far view, and extrapolating from it cost
    2.6e-6 px (the rule before ``geometry.FIT_RADIUS``)."""
    size = (512, 4096)
    cams = [reference(size, 0.05), camera(85, 10, 1.0, 120, size), camera(85, 200, 100.0, 120, size)]
    check_pairs(cams, size)


@pytest.mark.parametrize("tilt", [89.0, 89.9])
@pytest.mark.parametrize("size", [SIZE, (512, 4096)])
def test_fit_points_nearly_collinear_in_one_view(tilt, size):
    """At 89.9 degrees the fit square is 1:570 flat in the grazing view. Kornia's ``"svd"``
    solver, which takes the null vector of ``A^T A``, was off by up to 2.6e-4 px there; the
    ``"lu"`` path on ``A`` stays near the float64 floor."""
    for distance, fov in [(0.05, 120), (0.05, 60), (1.0, 10)]:
        grazing = camera(tilt, 30, distance, fov, size)
        fit = geometry.project(grazing.K, grazing.R, grazing.t,
                               geometry.fit_points(np.stack([grazing.position, np.array([0, 0, 0.9])])))
        flat = np.linalg.svd(fit - fit.mean(0), compute_uv=False)
        assert flat[1] / flat[0] < 0.1  # really nearly collinear
        check_pairs([reference(size, 0.9), grazing], size)


@pytest.mark.parametrize("kind", ["reference", "tilted"])
def test_h22_near_zero_is_finite_det_one_and_right(kind):
    """Pixel (0, 0) of view i sees the plane point ``X0``; camera j is placed so that ``X0`` lies
    (almost) on its principal plane, so ``H[i, j]`` sends (0, 0) to (near) the line at infinity
    and ``H[i, j][2, 2]`` is (near) 0. Normalising by it would blow up or flip the sign."""
    source = reference(SIZE, 0.9) if kind == "reference" else camera(35, 200, 1.2, 70, SIZE)
    X0 = cast(source, np.array([[0.0, 0.0]]))[0]
    # Centres C with X0 . C = |C|^2 put X0 at depth 0 in a camera aimed at the origin; scaling C
    # by s = 1 + delta puts it at depth ~ delta |C| / 2, in front (delta > 0) or behind.
    on_sphere = X0 / 2 + np.linalg.norm(X0) / 2 * np.array([0.0, 0.0, 1.0])
    for delta in (0.0, 1e-12, -1e-12, 1e-9, -1e-9, 1e-6, -1e-6, 1e-3, -1e-3):
        position = (1 + delta) * on_sphere
        R, t = geometry.look_at(position)
        target = Camera(geometry.intrinsics_from_fov(80, SIZE), R, t)
        depth_x0 = depth(target, X0[None])[0]
        H, _, _ = homographies([source, target], SIZE)
        h22 = H[0, 1, 2, 2]
        assert abs(h22) <= max(1e-9, 10 * abs(delta)) * np.abs(H[0, 1]).max()
        if abs(delta) >= 1e-6:
            assert np.sign(h22) == np.sign(depth_x0) == np.sign(delta)  # X0 in front of j iff w > 0
        check_pairs([source, target], SIZE)
        # float32, as handed out: still finite, det 1, and the sign survives.
        H32 = torch.from_numpy(H).float()
        assert torch.isfinite(H32).all()
        assert torch.allclose(torch.linalg.det(H32.double()), torch.ones(2, 2, dtype=torch.float64), atol=1e-6)


def test_normalising_by_h22_would_have_failed():
    """The sign check above is not vacuous: the same homography scaled by ``H[2, 2]`` instead of
    det = 1 sends the shared points behind the camera when ``H[2, 2] < 0``."""
    source = reference(SIZE, 0.9)
    X0 = cast(source, np.array([[0.0, 0.0]]))[0]
    position = (1 - 1e-3) * (X0 / 2 + np.linalg.norm(X0) / 2 * np.array([0.0, 0.0, 1.0]))
    target = Camera(geometry.intrinsics_from_fov(80, SIZE), *geometry.look_at(position))
    H, _, _ = homographies([source, target], SIZE)
    _, xi, _ = shared_points([source, target], SIZE, 0, 1)
    assert H[0, 1, 2, 2] < 0
    assert (transfer(H[0, 1], xi)[1] > 0).all()
    assert (transfer(H[0, 1] / H[0, 1, 2, 2], xi)[1] < 0).all()


def test_ill_conditioned_pair_is_bounded_by_float64_resolution():
    """Ill-conditioned on purpose, at the corners of the ranges: a far grazing view where the
    shared painting spans about 0.6 x 12 px is mapped onto a close grazing view where it spans
    4096 px (M ~ 1e6). Rounding the view-i pixel coordinate to float64 alone moves its image by
    ~6e-7 px there, so even the exact homography is off by about that much; the DLT stays within
    a small multiple of it (measured 9e-7 px, floor 5.7e-7 px)."""
    size = (4096, 4096)
    cams = [reference(size, 0.05), camera(85, 10, 0.05, 120, size), camera(85, 200, 100.0, 120, size)]
    worst = check_pairs(cams, size, relative=True)
    assert worst["floor"] > 1e-7  # ill-conditioned: the floor is near the target
    assert worst["projection"] <= 4 * worst["floor"]
    # The analytic homography, from the cameras themselves, does no better against projection.
    H_true = geometry.plane_induced_homographies(*sequence(cams, size).cameras())
    _, xi, xj = shared_points(cams, size, 2, 1)
    exact = np.linalg.norm(transfer(H_true[2, 1], xi)[0] - xj, axis=1).max()
    assert 0.1 * worst["projection"] < exact <= 4 * worst["floor"]


def test_known_limit_distance_ratio_1e5_with_a_grazing_camera():
    """Beyond the ranges, a second limit: the four fit points are shared by all views and must lie
    in front of every camera, so a grazing camera at 0.01 keeps them within 0.005 of the centre,
    and a view 1e5 times farther sees them within about 0.01 px. Their float64 round-off (~5e-13 px)
    is then 1e-10 of their spread, and extrapolating ~200 times to the painting that view shares
    costs ~2e-5 px in a view where the painting spans 4096 px (error ~ eps |x_i| M (E_i / s_i)^2,
    ``E_i / s_i`` the extrapolation). Within the hard-case ranges (0.05 to 100) this stays under
    the target. Fitting each pair on points chosen for that pair alone would remove it, but
    ``sequence_homographies`` fits all pairs on one set. If the error drops under 1e-6 px, the
    limit is gone: move this case into the strict tests."""
    size = (4096, 4096)
    cams = [reference(size, 0.01), camera(85, 10, 0.01, 120, size), camera(80, 200, 1000.0, 120, size)]
    far = cams[2]
    centres = np.stack([c.position for c in cams])
    spread = np.ptp(geometry.project(far.K, far.R, far.t, geometry.fit_points(centres)), axis=0)
    assert spread.max() < 0.02  # measured 0.011 px
    H, _, _ = homographies(cams, size)
    _, xi, xj = shared_points(cams, size, 2, 0)
    error = np.linalg.norm(transfer(H[2, 0], xi)[0] - xj, axis=1).max()
    assert 1e-6 < error < 1e-4  # measured 1.7e-5 px: over the target, and known


# --- property-based: random camera pairs ----------------------------------------------------------

@st.composite
def image_sizes(draw):
    h = draw(st.integers(1, 4096))
    return h, draw(st.integers(max(1, math.ceil(h / 8)), min(4096, 8 * h)))


@st.composite
def cameras(draw, size):
    distance = math.exp(draw(st.floats(math.log(0.05), math.log(100.0))))
    if draw(st.booleans()):
        return reference(size, distance)
    return camera(draw(st.floats(0, 85)), draw(st.floats(0, 360)), distance, draw(st.floats(10, 120)), size)


@st.composite
def camera_pairs(draw):
    size = draw(image_sizes())
    return size, [draw(cameras(size)), draw(cameras(size))]


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(camera_pairs())
def test_random_camera_pairs(pair):
    size, cams = pair
    check_pairs(cams, size, relative=True, n=11)


@settings(max_examples=50, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(camera_pairs(), st.data())
def test_random_camera_triples_share_fit_points(pair, data):
    """Three views share one set of fit points: the third camera constrains the first two."""
    size, cams = pair
    check_pairs(cams + [data.draw(cameras(size))], size, relative=True, n=9)


# --- the sampler ----------------------------------------------------------------------------------

SAMPLER_CASES = {
    "tilt 85": dict(max_tilt_deg=85, camera_xy=20.0),
    "fov 10": dict(fov_deg=(10, 10)),
    "fov 120": dict(fov_deg=(120, 120)),
    "height 1e-3": dict(camera_height=(1e-3, 1e-3), max_tilt_deg=60),
    "height 0.05": dict(camera_height=(0.05, 0.05), max_tilt_deg=60),
    "height 100": dict(camera_height=(100, 100)),
    "1 x 1": dict(image_size=(1, 1)),
    "3 x 5": dict(image_size=(3, 5)),
    "131 x 257": dict(image_size=(131, 257)),
    "64 x 512": dict(image_size=(64, 512)),
    "512 x 64": dict(image_size=(512, 64)),
    "1 x 8": dict(image_size=(1, 8)),
    "near, grazing, wide, 1:8": dict(max_tilt_deg=85, camera_xy=20.0, camera_height=(1e-3, 1e-3), fov_deg=(120, 120),
                                     image_size=(64, 512)),
    "far, grazing, narrow, 8:1": dict(max_tilt_deg=85, camera_xy=2000.0, camera_height=(100, 100), fov_deg=(10, 10),
                                      image_size=(512, 64)),
    "everything mixed": dict(max_tilt_deg=85, camera_xy=2000.0, camera_height=(1e-3, 100), fov_deg=(10, 120),
                             image_size=(131, 257)),
}


@pytest.mark.parametrize("name", SAMPLER_CASES)
def test_sampler_hard_configs(name):
    config = load_config("misaligned", n_views=4, **SAMPLER_CASES[name])
    for seed in range(3):
        seq = sample_sequence(config, np.random.default_rng([seed, 7]))
        cams = [view.camera for view in seq.views]
        assert check_pairs(cams, seq.image_size, n=11)["dataset"] <= TARGET_PX
        if "max_tilt_deg" in SAMPLER_CASES[name]:
            tilts = [math.degrees(math.acos(-c.R[2, 2])) for c in cams]
            assert max(tilts) <= 85 + 1e-9


def test_sampler_tilt_just_under_90_degrees_is_ill_conditioned_not_wrong():
    """``max_tilt_deg`` accepts anything under 90. At 89.99 with a wide ``camera_xy`` nearly every
    camera is ~3000 units away and grazing, so the painting covers a fraction of a pixel row in
    its view and the reference view magnifies that ~1e4 times: the error passes 1e-6 px (measured
    6e-6 px) but stays within the float64 floor's bound, and the dataset's own
    ``homography_error`` shows it (measured 3.6e-6 px), so it is not silent."""
    config = load_config("misaligned", n_views=4, max_tilt_deg=89.99, camera_xy=1e5)
    worst = 0.0
    for seed in range(3):
        seq = sample_sequence(config, np.random.default_rng([seed, 3]))
        figures = check_pairs([view.camera for view in seq.views], seq.image_size, relative=True, n=11)
        worst = max(worst, figures["projection"])
        assert figures["dataset"] > 1e-7
    assert worst < 1e-4


@pytest.mark.parametrize("field, value", [
    ("max_tilt_deg", 90.5), ("max_tilt_deg", -1), ("fov_deg", (0.5, 10)), ("fov_deg", (10, 180)),
    ("camera_height", (0.0, 1.0)), ("camera_height", (-1.0, 1.0)), ("image_size", (0, 5)), ("image_size", (5, 0)),
])
def test_configs_that_cannot_give_a_valid_view_are_rejected(field, value):
    with pytest.raises(ValueError, match=field):
        load_config("misaligned", **{field: value})


# --- float32, as the dataset hands them out --------------------------------------------------------

def float32_bound_px(H: np.ndarray, x: np.ndarray) -> np.ndarray:
    """First-order bound ``(N,)`` on how far rounding every entry of ``H`` to float32 (relative
    error <= 2^-24 each) moves ``x``'s image: ``u (|H| |x~|)_{0,1} + |x'| u (|H| |x~|)_2``, over
    ``|(H x~)_2|``. It grows where terms cancel, i.e. with the pair's magnification."""
    xt = np.concatenate([x, np.ones((len(x), 1))], 1)
    y, w = transfer(H, x)
    size = np.abs(xt) @ np.abs(H).T
    per_axis = EPS32 * (size[:, :2] + np.abs(y) * size[:, 2:]) / np.abs(w)[:, None]
    return np.linalg.norm(per_axis, axis=1)


def float32_roundoff(config, seeds) -> dict:
    """Worst float32 effects over sampled sequences: px at shared points and at image corners
    (of view i, where H64 sends them inside a box three times view j's size), and
    ``max |H32[i, j] @ H32[j, i] - I|`` in float32 arithmetic. Asserts the first-order bound."""
    worst = {"shared": 0.0, "corners": 0.0, "inverse": 0.0}
    for seed in seeds:
        seq = sample_sequence(config, np.random.default_rng([seed, 11]))
        size, cams = seq.image_size, [view.camera for view in seq.views]
        h, w = size
        H = sequence_homographies(seq)[0]
        H64, H32 = H.numpy(), H.float()
        H32d = H32.double().numpy()
        corners = geometry.corner_pixels(size)
        for i in range(len(cams)):
            for j in range(len(cams)):
                if i == j:
                    continue
                _, xi, _ = shared_points(cams, size, i, j, 11)
                y64 = transfer(H64[i, j], xi)[0]
                moved = np.linalg.norm(transfer(H32d[i, j], xi)[0] - y64, axis=1)
                assert (moved <= 1.01 * float32_bound_px(H64[i, j], xi) + 1e-12).all()
                c64, cw = transfer(H64[i, j], corners)
                near = (np.abs(c64[:, 0] - (w - 1) / 2) <= 1.5 * w) & (np.abs(c64[:, 1] - (h - 1) / 2) <= 1.5 * h)
                box = (cw > 0) & near
                if box.any():
                    c32 = transfer(H32d[i, j], corners[box])[0]
                    assert (np.linalg.norm(c32 - c64[box], axis=1)
                            <= 1.01 * float32_bound_px(H64[i, j], corners[box]) + 1e-12).all()
                    worst["corners"] = max(worst["corners"], float(np.linalg.norm(c32 - c64[box], axis=1).max()))
                worst["shared"] = max(worst["shared"], float(moved.max()))
                worst["inverse"] = max(worst["inverse"], (H32[i, j] @ H32[j, i] - torch.eye(3)).abs().max().item())
    return worst


def test_float32_roundoff_for_the_misaligned_preset():
    worst = float32_roundoff(load_config("misaligned"), range(6))
    assert worst["shared"] <= F32_TYPICAL_PX
    assert worst["corners"] <= F32_TYPICAL_PX
    assert worst["inverse"] <= F32_TYPICAL_PX
    assert worst["shared"] > 1e-6  # it is float32 round-off we measure, not float64's


F32_HARD = {
    # name: (overrides, documented bound in px at shared points: 3 to 5 times the worst of 20 sequences)
    "tilt 85": (dict(max_tilt_deg=85, camera_xy=20.0), 1e-2),
    "fov 10": (dict(fov_deg=(10, 10)), 1e-3),
    "fov 120": (dict(fov_deg=(120, 120)), 1e-3),
    "height 100": (dict(camera_height=(100, 100)), 1e-2),
    "64 x 512": (dict(image_size=(64, 512)), 1e-3),
    "4096 x 4096": (dict(image_size=(4096, 4096), n_views=3), 1e-2),
    # The painting seen by a camera 1e-3 above it covers ~1 px of the reference view: magnified
    # ~500 times, float32's 6e-8 relative round-off of a 500 px coordinate becomes ~0.05 px.
    "height 1e-3": (dict(camera_height=(1e-3, 1e-3), max_tilt_deg=60), 0.2),
}


@pytest.mark.parametrize("name", F32_HARD)
def test_float32_roundoff_in_hard_configs(name):
    overrides, bound = F32_HARD[name]
    worst = float32_roundoff(load_config("misaligned", **{"n_views": 4, **overrides}), range(3))
    assert worst["shared"] <= bound


# --- report: `python tests/test_hard_cases.py` ------------------------------------------------------

def _report() -> None:  # pragma: no cover - a measurement, not a test
    torch.set_num_threads(1)
    cases = {
        "grazing 85 deg": ((512, 4096), [reference((512, 4096), 0.9), camera(85, 30, 0.05, 120, (512, 4096)),
                                         camera(85, 210, 100.0, 10, (512, 4096))]),
        "fov 10 / 120": (SIZE, [reference(SIZE, 0.9), camera(40, 0, 1.0, 10, SIZE), camera(40, 120, 1.0, 120, SIZE)]),
        "close 0.05 / far 100": (SIZE, [reference(SIZE, 0.05), camera(60, 10, 0.05, 60, SIZE),
                                        camera(30, 100, 100.0, 10, SIZE)]),
        "coverage < 1e-4": (SIZE, [reference(SIZE, 0.9), camera(0, 0, 100.0, 120, SIZE)]),
        "aspect 1:8": ((64, 512), [reference((64, 512), 0.8), camera(85, 180, 2.0, 30, (64, 512))]),
        "1 x 1": ((1, 1), [reference((1, 1), 0.9), camera(80, 200, 0.3, 110, (1, 1))]),
        "tilt 89.9 (collinear)": ((512, 4096), [reference((512, 4096), 0.9), camera(89.9, 30, 0.05, 120, (512, 4096))]),
        "far + close grazing": ((512, 4096), [reference((512, 4096), 0.05), camera(85, 10, 1.0, 120, (512, 4096)),
                                              camera(85, 200, 100.0, 120, (512, 4096))]),
    }
    print("float64, px at shared points (target 1e-6):")
    for name, (size, cams) in cases.items():
        w = check_pairs(cams, size)
        print(f"  {name:24s} vs projection {w['projection']:.1e}  vs analytic {w['analytic']:.1e}  "
              f"float64 floor {w['floor']:.1e}  dataset homography_error {w['dataset']:.1e}")
    rng = np.random.default_rng(0)
    worst = 0.0
    for _ in range(300):
        h = int(rng.integers(1, 4097))
        size = (h, int(np.clip(round(h * math.exp(rng.uniform(-math.log(8), math.log(8)))), 1, 4096)))
        cams = [camera(rng.uniform(0, 85), rng.uniform(0, 360), math.exp(rng.uniform(math.log(0.05), math.log(100))),
                       rng.uniform(10, 120), size) for _ in range(3)]
        worst = max(worst, check_pairs(cams, size, relative=True, n=11)["projection"])
    print(f"  300 random triples (tilt 0-85, fov 10-120, distance 0.05-100, 1-4096 px, 1:8-8:1): worst {worst:.1e}")
    worst, floor = 0.0, 0.0
    extremes = [(d, f, t) for d in (0.05, 1.0, 100.0) for f in (10, 120) for t in (0, 85)]
    for size in [(4096, 4096), (512, 4096)]:
        for d0 in (0.05, 100.0):
            for a in range(len(extremes)):
                for b in range(a + 1, len(extremes)):
                    (d1, f1, t1), (d2, f2, t2) = extremes[a], extremes[b]
                    cams = [reference(size, d0), camera(t1, 10, d1, f1, size), camera(t2, 200, d2, f2, size)]
                    w = check_pairs(cams, size, relative=True, n=11)
                    if w["projection"] > worst:
                        worst, floor = w["projection"], w["floor"]
    print(f"  264 triples at the range corners (4096 px, 1:8): worst {worst:.1e} (float64 floor there {floor:.1e})")
    print("float32 round-off, px (shared points / image corners / max |H32 H32' - I|):")
    for name, overrides in [("misaligned 384x512", {})] + [(k, {"n_views": 4, **v[0]}) for k, v in F32_HARD.items()]:
        w = float32_roundoff(load_config("misaligned", **overrides), range(20))
        print(f"  {name:20s} {w['shared']:.1e} / {w['corners']:.1e} / {w['inverse']:.1e}")


if __name__ == "__main__":
    _report()
