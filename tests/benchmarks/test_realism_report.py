"""The realism report's statistics (``benchmarks/realism.py``), each on an image whose answer is known."""

import math

import numpy as np
import pytest
from scipy import ndimage

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


def figure(mean, interval, median=None):
    return realism.Figure(mean, interval, mean if median is None else median, 6)


def test_a_row_passes_only_when_our_mean_is_inside_blenders_interval():
    theirs = figure(100, (90, 110))
    assert realism.verdict(figure(105, (95, 115)), theirs) == ("1.05", "overlap", "yes")
    # within 10 % of Blender's mean (the old tolerance's pass) but outside its interval: out
    assert realism.verdict(figure(92, (85, 99)), figure(100, (95, 105))) == ("0.92", "overlap", "no")
    # intervals that overlap are printed as such but are not a pass
    assert realism.verdict(figure(120, (100, 140)), theirs) == ("1.20", "overlap", "no")
    assert realism.verdict(figure(150, (140, 160)), theirs) == ("1.50", "apart", "no")
    assert realism.verdict(figure(0.5, (0.4, 0.6)), figure(0.0, (0.0, 0.0))) == ("n/a", "apart", "no")
    # one sequence of ours: no interval of ours, still a verdict on our mean
    assert realism.verdict(figure(101, (np.nan, np.nan)), theirs) == ("1.01", "n/a", "yes")
    assert realism.verdict(figure(101, (95, 105)), figure(100, (np.nan, np.nan)))[2] == "no"


def test_the_interval_is_students_t_over_the_sequences_about_the_per_painting_mean():
    values = [np.array([v]) for v in (1.0, 2, 3, 4, 5, 6)]
    f = realism.per_painting(values, np.arange(6))
    half = 2.015048 * np.std(np.arange(1, 7), ddof=1) / np.sqrt(6)  # t(5) at 95 %: 2.015
    assert f.mean == 3.5 and f.interval == (pytest.approx(3.5 - half), pytest.approx(3.5 + half))
    assert f.sequences == 6 and f.median == 3.5
    # a bootstrap of the same six means reads narrower: the t interval is the honest one for six
    rng = np.random.default_rng(0)
    boot = np.percentile(rng.choice(np.arange(1, 7.0), (4000, 6)).mean(1), [5, 95])
    assert boot[1] - boot[0] < 0.85 * 2 * half
    # each painting counts once, whatever its number of sequences: three of painting 0 at 0, one of 1 at 1
    uneven = realism.per_painting([np.zeros(1)] * 3 + [np.ones(1)], np.array([0, 0, 0, 1]))
    assert uneven.mean == 0.5  # the pooled mean of the sequences would be 0.25
    # a sequence's value is the mean of its items (its views), NaN items dropped; a sequence of none is left out
    views = realism.per_painting([np.array([0.0, 1, np.nan]), np.array([np.nan]), np.array([2.0, 2])], np.arange(3))
    assert views.mean == pytest.approx(1.25) and views.sequences == 2
    # clipped at 0 for values that cannot be negative
    assert realism.per_painting([np.array([v]) for v in (0.0, 0, 0, 0, 0, 0.3)], np.arange(6)).interval[0] == 0
    assert np.isnan(realism.per_painting([np.array([1.0])], np.zeros(1)).interval[0])  # one sequence: none


def test_a_fraction_has_at_least_the_exact_binomial_interval_not_a_point_at_zero():
    none = realism.per_painting([np.zeros(6, bool)] * 6, np.arange(6), fraction=True)
    assert none.mean == 0 and none.interval[0] == 0 and none.interval[1] == pytest.approx(0.0798, abs=1e-4)
    assert (1 - none.interval[1]) ** 36 == pytest.approx(0.05)  # seeing 0 of 36 has probability 5 % there
    low, high = realism.binomial_interval(6, 36)
    assert sum(math.comb(36, k) * low**k * (1 - low) ** (36 - k) for k in range(6, 37)) == pytest.approx(0.05)
    assert sum(math.comb(36, k) * high**k * (1 - high) ** (36 - k) for k in range(0, 7)) == pytest.approx(0.05)
    # 3 of 144 views is inside 0 of 36's interval
    ours = realism.per_painting([np.arange(6) < (k < 3) for k in range(24)], np.arange(24) % 6, fraction=True)
    assert ours.mean == pytest.approx(3 / 144) and realism.verdict(ours, none)[2] == "yes"
    assert ours.median == pytest.approx(3 / 144)  # a fraction's pooled figure is the pooled fraction
    # sequences that disagree widen it past the binomial one: 0 or all of each sequence's views
    split = realism.per_painting([np.full(6, k % 2 == 0) for k in range(6)], np.arange(6), fraction=True)
    exact = realism.binomial_interval(18, 36)
    assert split.interval[0] < exact[0] and split.interval[1] > exact[1] and split.interval[1] <= 1


def painting_texture(size=(96, 128), seed=0):
    """Linear albedo with detail at every scale (blocks of 8, 2 and 1 pixels)."""
    rng = np.random.default_rng(seed)
    h, w = size
    coarse = rng.uniform(0.2, 0.8, (h // 8, w // 8)).repeat(8, 0).repeat(8, 1)
    medium = rng.uniform(-0.1, 0.1, (h // 2, w // 2)).repeat(2, 0).repeat(2, 1)
    return np.clip(coarse + medium + rng.uniform(-0.05, 0.05, size), 0, 1)


def test_detail_gain_is_one_for_the_painting_warped_and_below_one_blurred():
    h, w = SIZE
    albedo = painting_texture()
    source = encode(np.repeat(albedo[..., None], 3, -1))
    H = shift(5, 3)
    region = realism.painting_region(H, SIZE)
    seen = np.full(SIZE, np.nan)
    seen[3:, 5:] = albedo[:-3, :-5]
    y, x = np.mgrid[0:h, 0:w]
    light = 0.2 + 0.5 * x / w  # uneven, and far from 1: the light's level does not count
    visible = np.ones(SIZE, bool)
    visible[40:60, 60:80] = False  # an occluder, painted white in the view: its edge is not detail
    ring = ndimage.binary_dilation(~visible) & visible  # its antialiased edge, under half covered: mask 0
    linear = np.where(visible, np.nan_to_num(seen) * light, 1.0)
    linear[ring] = 0.6 * linear[ring] + 0.4
    sharp = realism.detail_gain(encode(np.repeat(linear[..., None], 3, -1)), source, H, visible, region)
    assert sharp[0] == pytest.approx(1.0, abs=0.02)
    blurred = ndimage.gaussian_filter(np.nan_to_num(seen), 1.0) * light
    soft = realism.detail_gain(encode(np.repeat(np.where(visible, blurred, 1.0)[..., None], 3, -1)), source, H,
                               visible, region)
    assert soft[0] < 0.5
    softer = ndimage.gaussian_filter(np.nan_to_num(seen), 2.0) * light
    assert realism.detail_gain(encode(np.repeat(softer[..., None], 3, -1)), source, H, visible, region)[0] < soft[0]
    # at scale 1 every pixel is resolved: no minified figure
    assert np.isnan(sharp[1]) and sharp[2] == sharp[0]


def test_detail_gain_of_a_minified_view_by_scale():
    """A view 0.4 times the painting's size: every pixel is minified. Drawn unfiltered (point sampled)
    it gains 1; averaged over each pixel's footprint, as a path tracer's pixel does, less."""
    big = painting_texture((240, 320), seed=3)
    source = encode(np.repeat(big[..., None], 3, -1))
    H = np.diag([0.4, 0.4, 1.0])
    H[:2, 2] = 0.4 * 0.5 - 0.5  # pixel centres at integers: x' = 0.4 (x + 0.5) - 0.5
    size = (240, 320)
    scale = realism.local_scale(H, size)
    assert np.allclose(scale, 0.4)
    x, y = realism.inverse_map(H, size)
    inside = (x <= 319.5) & (y <= 239.5)
    region = realism.painting_region(H, size)
    point = ndimage.map_coordinates(big, [np.where(inside, y, 0), np.where(inside, x, 0)], order=3, mode="nearest")
    view = encode(np.repeat(np.where(inside, point, 0)[..., None], 3, -1))
    gain = realism.detail_gain(view, source, H, inside, region)
    assert np.isnan(gain[2]) and gain[1] == gain[0] == pytest.approx(1.0, abs=0.05)
    box = ndimage.uniform_filter(big, 5)[1::5, 1::5]  # each view pixel the mean of its 2.5 x 2.5 footprint
    footprint = np.zeros(size)
    footprint[:96, :128] = ndimage.zoom(box, 2, order=1)[:96, :128]
    filtered = realism.detail_gain(encode(np.repeat(np.where(inside, footprint, 0)[..., None], 3, -1)), source, H,
                                   inside, region)
    assert filtered[1] < 0.7


def test_local_scale_is_the_smaller_singular_value_of_the_maps_jacobian():
    assert np.allclose(realism.local_scale(np.diag([1.0, 0.3, 1.0]), SIZE), 0.3)
    assert np.allclose(realism.local_scale(np.diag([2.0, 3.0, 1.0]), SIZE), 2.0)
    H = np.array([[0.9, 0.2, 4.0], [-0.1, 0.7, 3.0], [4e-4, 1e-3, 1.0]])
    scale = realism.local_scale(H, SIZE)
    G = np.linalg.inv(H)
    u, v, e = 70.0, 40.0, 1e-4

    def to_painting(u, v):
        p = G @ [u, v, 1]
        return p[:2] / p[2]

    J = np.stack([(to_painting(u + e, v) - to_painting(u - e, v)) / (2 * e),
                  (to_painting(u, v + e) - to_painting(u, v - e)) / (2 * e)], axis=1)
    assert scale[40, 70] == pytest.approx(1 / np.linalg.svd(J, compute_uv=False)[0], rel=1e-5)


def test_dark_area_counts_light_below_a_quarter_of_the_median():
    h, w = SIZE
    albedo = painting_texture()
    light = np.ones(SIZE)  # the median light
    light[:20] = 0.2  # a fifth of it: dark
    light[80:] = 0.3  # 0.3 of it: not dark
    view = encode(np.repeat((albedo * light)[..., None], 3, -1))
    label = encode(np.repeat(albedo[..., None], 3, -1)).astype(np.float64)
    region = realism.painting_region(np.eye(3), SIZE)  # rows 2-93
    visible = np.ones(SIZE, bool)
    fraction = realism.dark_area(view, label, visible, region)
    # 18 of the region's 92 rows are dark; the light is smoothed by 3 px, which lifts the 4-5 rows next to
    # the lit ones above a quarter
    assert (18 - 6) / 92 <= fraction <= 18 / 92
    hidden = visible.copy()
    hidden[:, : w // 2] = False  # an occluder over the left half: the same fraction of what is seen
    assert realism.dark_area(view, label, hidden, region) == pytest.approx(fraction, abs=0.02)
    assert realism.dark_area(encode(np.repeat(albedo[..., None], 3, -1)), label, visible, region) == 0


def test_table_prints_per_painting_rows_and_our_diagnostics_without_a_verdict():
    rng = np.random.default_rng(0)
    fields = [f.name for f in realism.dataclasses.fields(realism.ViewStats)]
    values = {name: rng.uniform(0.01, 0.5, 12) for name in fields}
    values.update(view=np.tile(np.arange(6.0), 2), sequence=np.repeat([0.0, 1.0], 6), painting=np.repeat([0.0, 1.0], 6))
    views = realism.ViewStats(**values)
    sequences = [realism.SequenceStats(0.6, realism.MatcherStats(np.full(6, 100), np.full(15, 20), np.ones(15)), k)
                 for k in range(2)]
    rows = {line.split(" | ")[0].lstrip("| "): line for line in
            realism.table("preset", views, sequences, views, sequences).splitlines() if line.startswith("| ")}
    diagnostics = [label for label, *_ in realism.DIAGNOSTICS]
    assert len(diagnostics) == 3 and all(label in rows for label in diagnostics)
    for label in ("detail gain, views 1-5", "occluder coverage of the painting region",
                  f"dark area (light < {realism.DARK_LIGHT:g} of the view's median light)",
                  "pairs matched (SIFT + RANSAC corner error < 3 px)"):
        assert label in rows
    for label, line in rows.items():
        cells = [c.strip() for c in line.strip("| ").split(" | ")]
        assert len(cells) == 7
        if label in diagnostics:  # no Blender figure and no verdict, our figure still printed
            assert cells[2] == "n/a" and cells[6] == "diagnostic" and cells[1] != "n/a"
        elif label == "occluders per view (ours: scene, bounding spheres)":  # against Blender's mask components
            assert cells[6] in ("yes", "no")
        elif label != "statistic":
            assert cells[6] == "yes" and cells[5] == "overlap"  # the same views on both sides
    exact = rows["cast-shadow fraction (ours exact: vs shadows=False)"]
    assert "of ours estimated" in exact  # the estimate's recall: exact over our own estimate
    twin = [line for label, line in rows.items() if "false shadows" in label][0]
    assert "near 0" in twin and "of ours estimated" not in twin
    verdicts = [label for label, *_ in realism.STATISTICS] + [label for label, _ in realism.SEQUENCE_STATISTICS]
    assert not set(verdicts) & set(diagnostics)
