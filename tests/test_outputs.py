"""The optional outputs' table (``choices.outputs.OUTPUTS``) and the layers that follow it name the same outputs."""

import pytest

from sidar_torch import load_config
from sidar_torch.config import SidarConfig
from sidar_torch.config.memory import estimated_sample_bytes
from sidar_torch.render.settings import RenderSettings
from sidar_torch.choices.outputs import OUTPUTS
from sidar_torch.sample import KEYS, LENS_KEYS, SampleArrays


def test_every_optional_output_is_a_config_switch_a_sample_key_and_a_sample_arrays_field():
    keys = {key.name: key for key in KEYS}
    assert {key.name for key in KEYS if key.switch is not None} == set(OUTPUTS) | set(LENS_KEYS)
    for name in LENS_KEYS:  # made by the lens step after read-back, not the renderer
        assert keys[name].entry is None and name in SampleArrays.__dataclass_fields__, name
        assert keys[name].switch in SidarConfig.__dataclass_fields__, name
    for name, row in OUTPUTS.items():
        assert isinstance(SidarConfig.__dataclass_fields__[row.switch].default, bool), row.switch
        assert (keys[name].switch, keys[name].entry) == (row.switch, row.entry), name
        assert keys[name].shape == f"(V, {row.channels}, H, W)", name
        assert name in SampleArrays.__dataclass_fields__, name


def test_a_switch_turns_its_output_on_in_the_render_settings_and_counts_in_the_memory_estimate():
    plain = load_config("misaligned")
    assert RenderSettings.from_config(plain).outputs == frozenset()
    for name, row in OUTPUTS.items():
        config = plain.replace(**{row.switch: True})
        assert RenderSettings.from_config(config).outputs == {row.computed_from or name}
        more = estimated_sample_bytes(config) - estimated_sample_bytes(plain)
        assert more == config.image_size[0] * config.image_size[1] * (config.n_views * row.view_pixel_bytes
                                                                      + row.target_pixel_bytes), name


def test_every_output_names_a_producer_of_the_renderer_or_a_computation_of_the_sample():
    from sidar_torch.render.renderer import OUTPUT_PASSES
    from sidar_torch.sample import COMPUTATIONS

    for name, row in OUTPUTS.items():
        table = COMPUTATIONS if row.computed_from is not None else OUTPUT_PASSES
        assert row.producer in table, name
        if row.computed_from is not None:
            assert OUTPUTS[row.computed_from].computed_from is None, name  # computed from a drawn output
    producers = {row.producer for row in OUTPUTS.values()}
    assert set(OUTPUT_PASSES) | set(COMPUTATIONS) == producers  # no producer without its output


def test_a_lens_refuses_exactly_the_outputs_it_may_not_resample():
    plain = load_config("misaligned", lens_model="division")
    for row in OUTPUTS.values():
        if row.lens_resample:
            assert getattr(plain.replace(**{row.switch: True}), row.switch)
        else:
            with pytest.raises(ValueError, match=f"config field '{row.switch}': expected false with lens_model"):
                plain.replace(**{row.switch: True})
