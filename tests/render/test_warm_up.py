"""The warm-up (``sidar_torch.sample.warm_up``): every program a preset's samples draw is compiled before
the first sample, and warming up hands out nothing and changes no pixel."""

import numpy as np
import pytest

from sidar_torch import SidarDataset, available_presets, load_config
from sidar_torch.render import RenderSettings, SceneRenderer
from sidar_torch.render.resample import LensResampling
from sidar_torch.sample.lens_views import render_through_lens
from sidar_torch.scene import sample_sequence
from sidar_torch.sample.warm_up import light_group_counts, variant_signature, warm_up_renderer, warm_up_sequence

from conftest import small_config, textured_painting

pytestmark = pytest.mark.gl  # renders


def painting_of(dataset, index):
    return dataset.source.painting(index % len(dataset.source), dataset.config.image_size)


def assert_no_sample_compiles_after_the_warm_up(config, samples, draw):
    """Warm a fresh renderer for ``config`` up, then ``draw(renderer, sequence, painting)`` its dataset's first
    ``samples`` samples: none may compile a program."""
    renderer = SceneRenderer(RenderSettings.from_config(config))
    try:
        assert renderer.warm_up(warm_up_sequence(config), "all variants")
        compiled = renderer.program_count
        dataset = SidarDataset(config=config, seed=0)
        for index in range(samples):
            draw(renderer, dataset.scene(index), painting_of(dataset, index))
            assert renderer.program_count == compiled, f"sample {index} compiled a program"
    finally:
        renderer.close()


@pytest.mark.parametrize("preset", available_presets())
def test_after_the_warm_up_no_sample_of_a_preset_compiles_a_program(preset):
    # Without the warm-up, samples 1 and 3 of aligned (and 1 of misaligned, paper_aligned) each add
    # programs to the 13 the first sample compiles.
    assert_no_sample_compiles_after_the_warm_up(load_config(preset, image_size=(48, 64)), 24,
                                               lambda renderer, sequence, painting: renderer.render(sequence, painting))


@pytest.mark.parametrize("preset, overrides", [("lens", {}), ("misaligned", {"lens_model": "brown_conrady"})])
def test_after_the_warm_up_no_lens_view_compiles_its_resampling_program(preset, overrides):
    # The resampling pass (render.resample) has a program per lens model and Newton steps; the warm-up
    # draws its views through the identity lens, which compiles the one these views take. (Warmed up
    # without the lens, the first sample compiled it.)
    def draw(renderer, sequence, painting):
        assert (LensResampling.of(sequence).steps <= 2).all()  # what the identity lens takes
        render_through_lens(renderer, sequence, painting)

    assert_no_sample_compiles_after_the_warm_up(load_config(preset, image_size=(48, 64), **overrides), 12, draw)


def test_the_warm_up_meets_every_variant_of_the_configs_materials():
    config = small_config("paper_misaligned")
    sequence = warm_up_sequence(config)
    assert sequence.image_size == config.image_size
    everything, opaque, unlit, empty = sequence.views[:4]
    drawn = {variant_signature(o.material) for o in everything.occluders}
    rng = np.random.default_rng(1)
    for _ in range(20):  # what samples draw is among the warm-up's variants
        for view in sample_sequence(config, rng).views:
            assert {variant_signature(o.material) for o in view.occluders} <= drawn
    assert len(drawn) == len(everything.occluders) >= 3
    assert all(variant_signature(o.material)[2] for o in opaque.occluders) and len(opaque.occluders) < len(drawn)
    assert everything.lights and not unlit.lights and unlit.occluders == everything.occluders
    assert not empty.occluders
    # Then, per number of light groups, a view with every occluder and one without.
    counts = light_group_counts(config)
    assert [len(v.lights) for v in sequence.views[4:]] == [n for n in counts for _ in range(2)]
    assert [len(v.occluders) for v in sequence.views[4:]] == [len(everything.occluders), 0] * len(counts)
    assert all(len(light.emitters) == 1 for v in sequence.views[4:] for light in v.lights)


def test_the_warm_up_hands_out_nothing_and_changes_no_pixel():
    config = small_config("misaligned", shadow_free_output=True, opacity_output=True, shadow_mask_output=True)
    settings = RenderSettings.from_config(config)
    sequence = sample_sequence(config, np.random.default_rng(3))
    painting = textured_painting(config.image_size)
    cold, warm = SceneRenderer(settings), SceneRenderer(settings)
    try:
        expected = cold.render(sequence, painting)
        assert warm.warm_up(warm_up_sequence(config), "key")
        assert not warm.skipped  # the warm-up's work is counted nowhere
        assert not warm.warm_up(warm_up_sequence(config), "key")  # once per key
        got = warm.render(sequence, painting)
        assert expected.outputs.keys() == got.outputs.keys() == {"opacities", "shadow_masks", "shadow_free"}
        pairs = [(n, getattr(expected, n), getattr(got, n)) for n in ("views", "masks", "label", "background")]
        for name, a, b in pairs + [(n, expected.outputs[n], got.outputs[n]) for n in expected.outputs]:
            assert np.array_equal(a, b), f"{name}: {int((a != b).sum())} values differ"
        assert warm.skipped == cold.skipped
        assert warm.program_count > cold.program_count  # it compiled variants this sample does not meet
    finally:
        cold.close()
        warm.close()


def test_a_fresh_renderer_hands_its_first_sample_out_before_its_warm_up():
    """A process that never rendered (a DataLoader worker of a parent that never did) compiles only what
    its first sample draws, then warms up before the second (``SidarDataset.renderer``, the edge that owns
    the renderer): the first sample comes sooner, the stream after it meets no compile, and the pixels are
    those of a warm renderer."""
    from sidar_torch.render import shared_renderer

    config = small_config("misaligned", image_size=(40, 56))  # a size no other test renders: a fresh renderer
    settings = RenderSettings.from_config(config)
    dataset = SidarDataset(config=config, seed=0)
    fresh = shared_renderer(settings)
    assert fresh.renders == 0
    warm = SceneRenderer(settings)
    try:
        warm.warm_up(warm_up_sequence(config), "all variants")
        first = dataset.sample_arrays(0)
        assert 0 < fresh.program_count < warm.program_count  # the first sample's variants only
        dataset.sample_arrays(1)
        assert fresh.program_count == warm.program_count  # warmed up before the second
        assert np.array_equal(first.images, warm.render(dataset.scene(0), painting_of(dataset, 0)).views)
    finally:
        warm.close()


def test_the_sample_path_compiles_nothing_ahead_and_takes_only_its_configs_renderer():
    """``render_arrays`` draws with the renderer it is handed and never warms it up (its owner does);
    a renderer made for other settings is refused, naming the fields that differ."""
    from sidar_torch.sample import render_arrays

    config = small_config("misaligned", image_size=(40, 56))
    dataset = SidarDataset(config=config, seed=0)
    renderer = SceneRenderer(RenderSettings.from_config(config))
    try:
        for index in range(2):
            render_arrays(renderer, dataset.scene(index), painting_of(dataset, index), config, index)
        assert renderer.renders == 2
        assert warm_up_renderer(renderer, config)  # nothing warmed it up before
        assert not warm_up_renderer(renderer, config)
        with pytest.raises(ValueError, match="renderer: expected one made for config's settings .* shadow_map_size"):
            render_arrays(renderer, dataset.scene(0), painting_of(dataset, 0), config.replace(shadow_map_size=64), 0)
    finally:
        renderer.close()
