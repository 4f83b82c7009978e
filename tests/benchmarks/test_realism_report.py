"""The realism report's statistics (``benchmarks/realism.py``), each on an image whose answer is known."""

import math

import numpy as np
import pytest

from sidar_torch import geometry
from sidar_torch.scene import Camera, Material, Occluder, ViewScene

from benchmarks import realism

SIZE = (96, 128)


def encode(linear):
    """Linear light in [0, 1] to 8-bit sRGB (exact curve)."""
    c = np.clip(linear, 0, 1)
    return np.round(255 * np.where(c <= 0.0031308, 12.92 * c, 1.055 * c ** (1 / 2.4) - 0.055)).astype(np.uint8)


def grey(level, size=SIZE):
    return np.full((*size, 3), level, np.uint8)


def shift(dx, dy=0.0):
    return np.array([[1.0, 0, dx], [0, 1, dy], [0, 0, 1]])


def test_luma_and_luminance_of_primaries():
    colours = np.array([[255, 255, 255], [255, 0, 0], [0, 255, 0], [0, 0, 0]], np.uint8)
    assert np.allclose(realism.luma(colours), [255, 0.2126 * 255, 0.7152 * 255, 0])
    assert np.allclose(realism.luminance(colours), [1, 0.2126, 0.7152, 0])
    assert np.isclose(realism.luminance(np.array([188, 188, 188], np.uint8)), 0.5, atol=0.003)  # sRGB 188 ~ half light


def test_painting_region_follows_the_homography_and_its_margin():
    h, w = SIZE
    assert realism.painting_region(np.eye(3), SIZE, margin=0).all()
    inner = realism.painting_region(np.eye(3), SIZE, margin=2)
    assert inner[2:-2, 2:-2].all() and inner.sum() == (h - 4) * (w - 4)
    moved = realism.painting_region(shift(10), SIZE, margin=0)  # the label lands 10 px to the right
    assert not moved[:, :10].any() and moved[:, 10:].all()


def test_warp_label_moves_the_label_by_the_homography():
    label = np.random.default_rng(0).integers(0, 256, (*SIZE, 3), dtype=np.uint8)
    warped = realism.warp_label(label, shift(5, 3))
    assert np.array_equal(warped[3:, 5:], label[:-3, :-5])
    assert np.isnan(warped[:3]).all() and np.isnan(warped[:, :5]).all()


def test_paper_homographies_are_conjugated_to_pixel_centres():
    h, w = SIZE
    S = np.array([[(w - 1) / w, 0, (w - 1) / (2 * w)], [0, (h - 1) / h, (h - 1) / (2 * h)], [0, 0, 1]])
    H_paper = np.array([[0.9, 0.1, 12.0], [-0.05, 1.1, -4.0], [1e-4, -2e-4, 1.0]])
    H = realism.paper_to_kornia(H_paper, SIZE)
    points = np.array([[-0.5, -0.5, 1], [w - 0.5, -0.5, 1], [30.0, 40.0, 1]]).T
    ours, theirs = S @ (H @ points), H_paper @ (S @ points)
    assert np.allclose(ours[:2] / ours[2], theirs[:2] / theirs[2])
    assert np.allclose((S @ points)[:2, :2], [[0, w - 1], [0, 0]])  # the image's edges are 0 and W - 1 there


def exact_fraction(lit, unshadowed, painting):
    return realism.shadow_fraction(realism.exact_light_ratio(lit, unshadowed, painting))


def test_cast_shadow_fraction_counts_pixels_darkened_by_more_than_half():
    unshadowed = grey(200)
    lit = unshadowed.copy()
    h, w = SIZE
    lit[:, : w // 4] = encode(0.2 * realism.luminance(grey(200))[0, 0])  # to 20 % of the light: shadow
    lit[:, w // 4: w // 2] = encode(0.6 * realism.luminance(grey(200))[0, 0])  # to 60 %: not a shadow
    painting = np.ones(SIZE, bool)
    assert exact_fraction(lit, unshadowed, painting) == pytest.approx(0.25)
    painting[:, w // 8: w // 4] = False  # an occluder over half the shadow
    assert exact_fraction(lit, unshadowed, painting) == pytest.approx((w // 8) / (w - w // 8))
    assert exact_fraction(grey(0), grey(0), np.ones(SIZE, bool)) == 0  # black: nothing judged dark


def test_shadow_darkness_is_the_median_light_ratio_of_darkened_pixels_only():
    unshadowed = grey(200)
    lit = unshadowed.copy()
    lit[:, :40] = encode(0.3 * realism.luminance(grey(200))[0, 0])  # a shadow passing 30 % of the light
    ratio = realism.exact_light_ratio(lit, unshadowed, np.ones(SIZE, bool))
    assert realism.shadow_darkness(ratio) == pytest.approx(0.3, abs=0.01)  # the lit rest does not count
    assert np.isnan(realism.shadow_darkness(realism.exact_light_ratio(unshadowed, unshadowed, np.ones(SIZE, bool))))


def test_estimated_shadow_fraction_finds_a_shadow_under_uneven_light_on_a_texture():
    h, w = 192, 256
    rng = np.random.default_rng(1)
    albedo = rng.uniform(0.2, 0.8, (h // 8, w // 8, 3)).repeat(8, 0).repeat(8, 1)  # a blocky painting
    y, x = np.mgrid[0:h, 0:w]
    light = 0.5 + 0.7 * x / w  # falls off across the painting by a factor 2.4
    shadow = (x - 80) ** 2 + (y - 100) ** 2 < 40**2
    view = encode(albedo * (light * np.where(shadow, 0.25, 1.0))[..., None])
    label = encode(albedo).astype(np.float64)
    painting = np.ones((h, w), bool)
    ratio = realism.estimated_light_ratio(view, label, painting, painting)
    assert realism.shadow_fraction(ratio) == pytest.approx(shadow.mean(), abs=0.02)
    # the hole is filled to its rim's lowest light, 0.61 on its left, where its centre has 0.72: 0.25 x 0.72 / 0.61
    assert realism.shadow_darkness(ratio) == pytest.approx(0.30, abs=0.05)
    no_shadow = encode(albedo * light[..., None])
    assert realism.shadow_fraction(realism.estimated_light_ratio(no_shadow, label, painting, painting)) < 0.005


def test_a_spot_pool_is_not_a_shadow_but_a_shadow_inside_it_is():
    """A spot's pool of light (8 times the light around it, its edge 6 px wide) leaves the rest of the
    painting dark out to its edges: shading, not a hole in the light. An occluder's shadow inside the
    pool is one, also where an occluder hides part of it."""
    h, w = 192, 256
    albedo = np.random.default_rng(2).uniform(0.2, 0.8, (h // 8, w // 8, 3)).repeat(8, 0).repeat(8, 1)
    y, x = np.mgrid[0:h, 0:w]
    light = 0.1 + 0.7 / (1 + np.exp((np.hypot(x - 140, y - 90) - 70) / 3))
    shadow = (x - 150) ** 2 + (y - 90) ** 2 < 25**2
    label = encode(albedo).astype(np.float64)
    painting, region = np.ones((h, w), bool), realism.painting_region(np.eye(3), (h, w))
    pool = realism.estimated_light_ratio(encode(albedo * light[..., None]), label, painting, region)
    assert realism.shadow_fraction(pool) < 0.005
    hidden = (x - 165) ** 2 + (y - 90) ** 2 < 12**2  # an occluder over part of its shadow
    view = encode(albedo * (light * np.where(shadow, 0.3, 1.0))[..., None])
    ratio = realism.estimated_light_ratio(view, label, ~hidden, region)
    assert realism.shadow_fraction(ratio) == pytest.approx((shadow & ~hidden)[region].mean(), abs=0.01)


def test_occluder_coverage_and_components():
    region = np.zeros(SIZE, bool)
    region[10:90, 10:110] = True
    mask = ~region  # the background
    mask[20:40, 20:40] = True  # an occluder of 400 px
    mask[60:70, 60:70] = True  # and one of 100 px
    mask[50, 50] = True  # a speck below MIN_COMPONENT
    assert realism.occluder_coverage(mask, region) == pytest.approx(501 / (80 * 100))
    assert realism.occluder_components(mask, region) == 2
    mask[40:60, 39] = True  # joining the first two (8-connected) makes them one
    mask[59, 40:60] = True
    assert realism.occluder_components(mask, region) == 1


def test_edge_sharpness_is_one_for_a_hard_step_and_a_half_for_a_two_pixel_ramp():
    h, w = SIZE
    mask = np.zeros(SIZE, bool)
    mask[:, 64:] = True
    region = np.ones(SIZE, bool)
    hard = grey(200)
    hard[:, 64:] = 40
    assert realism.edge_sharpness(hard, mask, region) == pytest.approx(1.0)
    ramp = hard.copy()
    ramp[:, 64] = 120  # antialiased: half the step on the edge pixel
    assert realism.edge_sharpness(ramp, mask, region) == pytest.approx(0.5)
    assert np.isnan(realism.edge_sharpness(grey(200), mask, region))  # no contrast, no figure


def test_occluders_over_painting_counts_what_the_view_sees_above_the_painting():
    camera = Camera(*geometry.reference_camera(SIZE, 0.9))
    material = Material(np.ones(4), 0.0, 1.0)
    above = Occluder("sphere", np.array([0.0, 0.0, 0.3]), np.eye(3), np.full(3, 0.05), material)
    aside = Occluder("sphere", np.array([3.0, 0.0, 0.3]), np.eye(3), np.full(3, 0.05), material)
    scene = ViewScene(camera, (), (above, aside), material, 0.0)
    region = realism.painting_region(np.eye(3), SIZE)
    assert realism.occluders_over_painting(scene, region) == 1


def test_verdict_ratio_and_tolerance():
    def figure(centre, interval=(0.0, 0.0), mean=None, mean_interval=(0.0, 0.0)):
        return realism.Figure(centre, centre, centre, centre if mean is None else mean, interval, mean_interval)

    assert realism.verdict(figure(105), figure(100)) == ("1.05", "yes")
    assert realism.verdict(figure(150), figure(100, (90, 120))) == ("1.50", "no")
    assert realism.verdict(figure(115), figure(100, (90, 120))) == ("1.15", "yes")
    assert realism.verdict(figure(0.5), figure(0.0)) == ("n/a", "no")
    # Blender's median 0 (most views have none): the means are compared, with the mean's interval
    assert realism.verdict(figure(0.0, mean=0.002), figure(0.0, mean=0.013, mean_interval=(0.004, 0.025))) \
        == ("0.15 (means)", "no")
    assert realism.verdict(figure(0.0, mean=0.010), figure(0.0, mean=0.013, mean_interval=(0.004, 0.025))) \
        == ("0.77 (means)", "yes")


def test_table_prints_our_diagnostics_without_a_verdict_against_blender():
    rng = np.random.default_rng(0)
    views = realism.ViewStats(*(rng.uniform(0.01, 0.5, 12) for _ in realism.dataclasses.fields(realism.ViewStats)))
    sequence = realism.SequenceStats(0.6, realism.MatcherStats(np.full(6, 100), np.full(15, 20), np.ones(15)))
    rows = {line.split(" | ")[0].lstrip("| "): line for line in
            realism.table("preset", views, [sequence], views, [sequence]).splitlines() if line.startswith("| ")}
    diagnostics = [label for label, *_ in realism.DIAGNOSTICS]
    assert len(diagnostics) == 3 and all(label in rows for label in diagnostics)
    for label, line in rows.items():
        cells = [c.strip() for c in line.strip("| ").split(" | ")]
        if label in diagnostics:  # no Blender figure and no verdict, our figure still printed
            assert cells[2] == "n/a" and cells[5] == "diagnostic" and cells[1] != "n/a"
        elif label != "statistic":
            assert cells[5] in ("yes", "no")
    exact = rows["cast-shadow fraction (ours exact: vs shadows=False)"]
    assert "of ours estimated" in exact  # the estimate's recall: exact over our own estimate
    twin = [line for label, line in rows.items() if "false shadows" in label][0]
    assert "near 0" in twin and "of ours estimated" not in twin
    verdicts = [label for label, *_ in realism.STATISTICS] + [label for label, _ in realism.SEQUENCE_STATISTICS]
    assert not set(verdicts) & set(diagnostics)


def test_dark_view_fraction_and_median_over_views():
    medians = np.array([10, 40, 60, 200, np.nan])
    assert realism.of_views(medians[:4] < realism.DARK_MEDIAN).centre == 0.5
    figure = realism.per_view(medians)
    assert (figure.centre, figure.low, figure.high) == (50, 32.5, 95)


def test_a_fraction_of_views_has_the_exact_binomial_interval_not_a_point_at_zero():
    none = realism.of_views(np.zeros(36, bool))
    assert none.centre == 0 and none.interval[0] == 0 and none.interval[1] == pytest.approx(0.0798, abs=1e-4)
    # at the upper end, seeing 0 of 36 has probability 5 %; at the lower end of 6 of 36, seeing 6 or more does
    assert (1 - none.interval[1]) ** 36 == pytest.approx(0.05)
    low, high = realism.of_views(np.arange(36) < 6).interval
    assert sum(math.comb(36, k) * low**k * (1 - low) ** (36 - k) for k in range(6, 37)) == pytest.approx(0.05)
    assert sum(math.comb(36, k) * high**k * (1 - high) ** (36 - k) for k in range(0, 7)) == pytest.approx(0.05)
    assert realism.of_views(np.ones(36, bool)).interval == (pytest.approx(1 - 0.0798, abs=1e-4), 1.0)
    # 3 of 144 views is inside 0 of 36's interval: no rate but 0 met the bootstrap's 0 - 0
    assert realism.verdict(realism.of_views(np.arange(144) < 3), none)[1] == "yes"
