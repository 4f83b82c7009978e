"""The painting's program without lookups, written out per number of light groups (quirk 6): the same
bytes as the loop, a variant per count, and the count the shader adds."""

import numpy as np
import pytest

from sidar_torch.render import RenderSettings, SceneRenderer, shared_renderer
from sidar_torch.render.draws import SpotEmitter
from sidar_torch.render.passes import light_group_count
from sidar_torch.scene import sample_sequence

from conftest import small_config, textured_painting

pytestmark = pytest.mark.gl  # renders


@pytest.mark.parametrize("shading", ["per_light", "per_emitter"])
def test_groups_written_out_give_the_bytes_of_the_loop(shading):
    """Views of 1 to 5 lights (area lights of 3 emitters among them), with and without casters and the
    shadow-free output: the written-out groups give the same bytes as the loop (a renderer whose
    unrolling limit is 0), and each count up to the limit has its program."""
    painting = textured_painting((64, 80))
    cfg = small_config(image_size=(64, 80), n_views=3, n_occluders=(0, 2), area_light_samples=3,
                       light_types=("spot", "point", "area"), area_light_shading=shading, shadow_free_output=True)
    settings = RenderSettings.from_config(cfg)
    unrolled = shared_renderer(settings)
    looped = SceneRenderer(settings)  # its own renderer: a program cache of its own
    looped._passes.unrolled_light_groups = 0
    try:
        for n in range(1, 6):
            for seed in range(2):
                seq = sample_sequence(cfg.replace(n_lights=(n, n)), np.random.default_rng(100 * n + seed))
                a, b = unrolled.render(seq, painting), looped.render(seq, painting)
                assert np.array_equal(a.views, b.views), (n, seed)
                assert np.array_equal(a.outputs["shadow_free"], b.outputs["shadow_free"]), (n, seed)
    finally:
        looped.close()
    counts = {defines.get("LIGHT_GROUPS") for defines in unrolled.program_variants}
    assert {1, 2, 3, 4} <= counts  # the painting's variants (per_emitter: 3 emitters of an area light are 3 groups)
    assert not any("LIGHT_GROUPS" in defines for defines in looped.program_variants)


def test_a_light_group_count_steps_over_each_group():
    # Groups of 3, 1 and 2 emitters: only a group's first light's size counts.
    lights = [SpotEmitter(np.eye(4), np.ones(3, np.float32), 1.0, 0.1, 0.2, rank, group_size=size)
              for rank, size in enumerate([3, 0, 0, 1, 2, 0])]
    assert light_group_count(lights) == 3
