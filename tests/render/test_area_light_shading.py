"""Quirk 13: the emitters of a light shaded once from their centre (``area_light_shading: per_light``),
each darkened by its own shadow lookup; lights of one emitter render the same bytes either way."""

from dataclasses import replace

import numpy as np
import pytest

from sidar_torch import geometry
from sidar_torch.render import RenderSettings, shared_renderer
from sidar_torch.render.plan import plan_views, whole_lights
from sidar_torch.scene import Camera, Light, Material, Occluder, SceneSequence, ViewScene, sample_sequence

from conftest import SMALL, WHITE, small_config, textured_painting

pytestmark = pytest.mark.gl


def render(settings, seq, painting, grouped):
    return shared_renderer(replace(settings, group_emitters=grouped)).render(seq, painting)


def overhead_view(emitters, occluders):
    camera = Camera(geometry.intrinsics_from_fov(60, SMALL), *geometry.look_at(np.array([0.1, -0.1, 1.2])))
    light = Light("area", np.asarray(emitters, float), np.ones(3), 3.0, 0.9, 1.1)
    return SceneSequence(SMALL, (ViewScene(camera, (light,), tuple(occluders), WHITE, 0.05),))


CUBE = Occluder("cube", np.array([0.05, 0.0, 0.3]), np.eye(3), np.full(3, 0.08),
                Material(np.array([0.8, 0.2, 0.2, 1.0]), 0.2, 0.3, coat=0.5))


def test_samples_at_one_point_give_the_same_bytes_shaded_once_or_each():
    # Four samples at one point: each emitter's shade and lookup are the group's, so the group's one
    # shade added four times, each darkened by its own emitter's lookup, is the per-emitter sum.
    seq = overhead_view([[0.2, 0.3, 1.5]] * 4, [CUBE])
    settings, painting = RenderSettings.from_config(small_config()), textured_painting(SMALL)
    (plan,) = plan_views(seq, settings)
    assert plan.n_shadowed == 4  # all four look their shadows up
    grouped, each = render(settings, seq, painting, True), render(settings, seq, painting, False)
    assert np.array_equal(grouped.views, each.views)
    unshadowed = render(settings, overhead_view([[0.2, 0.3, 1.5]] * 4, []), painting, True)
    assert (unshadowed.views.astype(int) - grouped.views > 40).sum() > 100  # the cube's shadow is there


def test_lights_of_one_emitter_render_the_same_bytes_either_way():
    cfg = small_config(n_views=3, n_occluders=(1, 3), light_types=("spot", "point"), n_lights=(2, 4))
    settings, painting = RenderSettings.from_config(cfg), textured_painting(SMALL)
    for seed in range(3):
        seq = sample_sequence(cfg, np.random.default_rng(seed))
        grouped, each = render(settings, seq, painting, True), render(settings, seq, painting, False)
        assert np.array_equal(grouped.views, each.views) and np.array_equal(grouped.masks, each.masks)


def test_spread_samples_shade_from_their_centre_with_one_highlight():
    # A glossy painting under an area light of four spread samples: shaded per emitter it shows four
    # highlights, per light one; away from the highlights the light is about the same.
    glossy = Material(np.array([0.5, 0.5, 0.5, 1.0]), 0.0, 0.08, specular=1.0)
    corners = [[x, y, 1.0] for x in (-0.25, 0.25) for y in (-0.2, 0.2)]
    camera = Camera(geometry.intrinsics_from_fov(70, SMALL), *geometry.look_at(np.array([0.0, 0.0, 1.0])))
    light = Light("area", np.array(corners), np.ones(3), 1.0, 1.2, 1.4)
    seq = SceneSequence(SMALL, (ViewScene(camera, (light,), (), glossy, 0.0),))
    settings, painting = RenderSettings.from_config(small_config()), np.full((*SMALL, 3), 128, np.uint8)
    grouped, each = (render(settings, seq, painting, g).views[0].astype(int).sum(axis=-1) for g in (True, False))

    def highlights(image):  # connected bright spots, counted by flood fill
        bright = image > image.max() - 60
        seen, count = np.zeros_like(bright), 0
        for start in zip(*np.nonzero(bright)):
            if seen[start]:
                continue
            count, stack = count + 1, [start]
            while stack:
                y, x = stack.pop()
                if 0 <= y < bright.shape[0] and 0 <= x < bright.shape[1] and bright[y, x] and not seen[y, x]:
                    seen[y, x] = True
                    stack += [(y + 1, x), (y - 1, x), (y, x + 1), (y, x - 1)]
        return count

    assert highlights(each) == 4 and highlights(grouped) == 1
    dim = (each < np.percentile(each, 50)) & (grouped < np.percentile(grouped, 50))
    assert np.abs(each[dim] - grouped[dim]).mean() < 0.05 * each[dim].mean()


def test_lookup_ranges_widen_to_whole_lights():
    lights = [2, 2, 2, 2, 0, 1, 1, 1, 1]
    begin, end = np.array([0, 1, 4, 5, 6, 3, 3]), np.array([1, 3, 5, 6, 9, 3, 7])
    wide_begin, wide_end = whole_lights(begin, end, lights)
    assert wide_begin.tolist() == [0, 0, 4, 5, 5, 3, 0] and wide_end.tolist() == [4, 4, 5, 9, 9, 3, 9]


def test_a_lights_emitters_are_shadowed_all_or_none():
    # A cube above the camera (out of its view): one sample of the area light, right above the cube,
    # throws its shadow into the view; the others, far to the side, throw it far outside. Per
    # emitter only that one is shadowed; per light all four.
    high = Occluder("cube", np.array([0.1, 0.1, 1.35]), np.eye(3), np.full(3, 0.05), CUBE.material)
    seq = overhead_view([[3.0, 3.0, 3.0], [0.2, 0.3, 1.5], [3.2, 3.0, 3.0], [3.0, 3.2, 3.0]], [high])
    settings = RenderSettings.from_config(small_config())
    (each,) = plan_views(seq, replace(settings, group_emitters=False))
    (grouped,) = plan_views(seq, settings)
    assert each.n_shadowed == 1 and each.order[0] == (0, 1)
    assert grouped.n_shadowed == 4 and grouped.order == tuple((0, b) for b in range(4))
