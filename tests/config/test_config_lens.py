"""The lens ranges a config accepts (``config.validation._check_lens``): no lens of the box the ranges span may
fold the view over the image (``choices.lenses.lens_folds``, tangential terms included; the renderer and the
export reader refuse a lens by the same function), the worst lens of a box being one of its corners."""

import itertools

import numpy as np
import pytest

from sidar_torch import available_presets, load_config
from sidar_torch.choices.lenses import LEAST_SLOPE, LENS_MODELS, lens_folds

FLAT = dict(lens_model="brown_conrady", lens_k2=(0.0, 0.0), lens_k3=(0.0, 0.0))


def edge_k1(p: float) -> float:
    """The lowest k1 (at the corner) of a lens (k1, 0, p, p, 0) that does not fold, by bisection."""
    low, high = -0.5, 0.0
    for _ in range(50):
        middle = (low + high) / 2
        low, high = (middle, high) if lens_folds("brown_conrady", [middle, 0.0, p, p, 0.0]) else (low, middle)
    return high


def folds_on_a_grid(corner: np.ndarray) -> bool:
    """lens_folds' test done by brute force on a polar grid of the undistorted disk (corner-scaled coordinates):
    the Jacobian by central differences, its smallest eigenvalue over the disk out to the least radius whose
    circle the lens maps outside the unit disk."""
    distort = LENS_MODELS["brown_conrady"].distort
    r, angle = np.linspace(0.0, 3.0, 1501)[:, None], np.linspace(0.0, 2 * np.pi, 721)[None, :]
    u, v, h = r * np.cos(angle), r * np.sin(angle), 1e-6
    (j11, j21), (j12, j22) = ((np.array(distort((u + h, v), corner)) - np.array(distort((u - h, v), corner))) / (2 * h),
                              (np.array(distort((u, v + h), corner)) - np.array(distort((u, v - h), corner))) / (2 * h))
    least = ((j11 + j22) / 2 - np.sqrt(((j11 - j22) / 2) ** 2 + j12 * j21)).min(axis=1)
    reached = np.hypot(*distort((u, v), corner)).min(axis=1) >= 1.0
    return not reached.any() or bool(least[:np.argmax(reached) + 1].min() <= LEAST_SLOPE)


def test_a_range_that_folds_only_by_its_tangential_terms_is_refused_naming_them():
    """k1 r^2 = -0.14 alone bends the view without folding it; with tangential terms of 0.01 a part of the image
    has no source (the renderer would refuse it mid-training): the config refuses it when made."""
    assert load_config("misaligned", **FLAT, lens_k1=(-0.14, 0.0), lens_p1=(0.0, 0.0), lens_p2=(0.0, 0.0))
    assert load_config("misaligned", **FLAT, lens_k1=(-0.14, 0.0))  # the default tangential ranges, +-0.002
    with pytest.raises(ValueError, match=r"config fields 'lens_k1', 'lens_k2', 'lens_p1', 'lens_p2', 'lens_k3': expected "
                                         r"ranges of lens_model 'brown_conrady' whose every lens bends the image "
                                         r"without folding it .*got lens_k1=\(-0.14, 0.0\), lens_k2=\(0.0, 0.0\), "
                                         r"lens_p1=\(-0.01, 0.01\), lens_p2=\(-0.01, 0.01\), lens_k3=\(0.0, 0.0\), whose "
                                         r"lens \(-0.14, 0.0, -0.01, -0.01, 0.0\) at the corner folds it \(with lens_p1 "
                                         r"and lens_p2 at 0 it would not: the tangential terms fold it\): narrow"):
        load_config("misaligned", **FLAT, lens_k1=(-0.14, 0.0), lens_p1=(-0.01, 0.01), lens_p2=(-0.01, 0.01))
    with pytest.raises(ValueError, match=r"lens_p2=\(0.01, 0.01\).*the tangential terms fold it"):  # one corner suffices
        load_config("misaligned", **FLAT, lens_k1=(-0.14, -0.14), lens_p1=(0.01, 0.01), lens_p2=(0.01, 0.01))
    with pytest.raises(ValueError, match=r"folds it: narrow"):  # radial terms that fold alone: no word on the others
        load_config("misaligned", **FLAT, lens_k1=(-0.3, 0.0), lens_p1=(0.0, 0.0), lens_p2=(0.0, 0.0))


def test_the_edge_of_folding_a_range_just_inside_passes_and_one_just_outside_is_refused():
    """Tangential terms of 0.01 move the edge from k1 r^2 = -0.148 (radial terms only) to -0.1200: -0.12 (the lens
    docs/lens.md calls nearly folding) passes, -0.1201 does not."""
    assert -0.1201 < edge_k1(0.01) < -0.12 and -0.149 < edge_k1(0.0) < -0.147
    assert load_config("misaligned", **FLAT, lens_k1=(-0.12, 0.05), lens_p1=(-0.01, 0.01), lens_p2=(-0.01, 0.01))
    with pytest.raises(ValueError, match=r"got lens_k1=\(-0.1201, 0.05\).*the tangential terms fold it"):
        load_config("misaligned", **FLAT, lens_k1=(-0.1201, 0.05), lens_p1=(-0.01, 0.01), lens_p2=(-0.01, 0.01))


def test_every_preset_and_the_default_lens_ranges_load():
    for name in available_presets():
        load_config(name)
    for model in LENS_MODELS:
        assert load_config("misaligned", lens_model=model).lens_model == model


@pytest.mark.parametrize("p", [0.0, 0.004, 0.01, -0.01])
def test_lens_folds_is_the_jacobian_test_on_a_grid(p):
    """lens_folds takes the least values over the angle in closed form; brute force on a polar grid (the Jacobian
    by differences) puts the edge where it does, tangential terms or not, and for lenses with k2 and k3."""
    edge = edge_k1(p)
    assert folds_on_a_grid(np.array([edge - 2e-3, 0.0, p, p, 0.0]))
    assert not folds_on_a_grid(np.array([edge + 2e-3, 0.0, p, p, 0.0]))
    rng = np.random.default_rng(round(abs(p) * 1e4) + (p < 0))
    for _ in range(4):
        corner = np.array([rng.uniform(-0.3, 0.5), rng.uniform(-0.3, 0.3), rng.uniform(-0.01, 0.01),
                           rng.uniform(-0.01, 0.01), rng.uniform(-0.3, 0.1)])
        assert bool(lens_folds("brown_conrady", corner)) == folds_on_a_grid(corner), corner


def test_without_tangential_terms_a_lens_folds_where_its_radius_stops_rising_before_the_corner():
    """The radial rule lens_folds reduces to: |s| a(|s|^2) rises with slope above LEAST_SLOPE until it reaches 1."""
    s = np.linspace(0.0, 3.0, 3001)
    rng = np.random.default_rng(3)
    corners = np.zeros((400, 5))
    corners[:, [0, 1, 4]] = rng.uniform(-0.5, 0.5, (400, 3)) * rng.integers(0, 2, (400, 3))
    for corner, folds in zip(corners, lens_folds("brown_conrady", corners)):
        c1, c2, _, _, c3 = corner
        value, slope = s * (1 + s**2 * (c1 + s**2 * (c2 + s**2 * c3))), 1 + s**2 * (3 * c1 + s**2 * (5 * c2 + 7 * c3 * s**2))
        reach = np.flatnonzero(value >= 1.0)
        assert folds == (len(reach) == 0 or slope[:reach[0] + 1].min() <= LEAST_SLOPE), corner


def test_the_worst_lens_of_a_box_of_ranges_is_one_of_its_corners():
    """What the config relies on, measured: in boxes within the fields' bounds none of whose 32 corners folds, no
    lens drawn inside folds either (a lens folds more the lower its radial coefficients, the larger |(p1, p2)|)."""
    rng = np.random.default_rng(0)
    boxes = 0
    for _ in range(400):
        low = np.concatenate([rng.uniform(-0.5, 0.4, 2), rng.uniform(-0.01, 0.01, 2), rng.uniform(-0.5, 0.4, 1)])
        high = np.minimum(low + rng.uniform(0.0, [0.3, 0.3, 0.02, 0.02, 0.3]), [0.5, 0.5, 0.01, 0.01, 0.5])
        if lens_folds("brown_conrady", np.array(list(itertools.product(*zip(low, high))))).any():
            continue
        boxes += 1
        assert not lens_folds("brown_conrady", rng.uniform(low, high, (100, 5))).any(), (low, high)
    assert boxes > 80
