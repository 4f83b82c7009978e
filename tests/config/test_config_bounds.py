"""Issue 25 item 4: every number a config accepts renders; everything else is a ``ValueError`` naming
the field when the config is made (never an ``OverflowError``, ``TypeError`` or ``LinAlgError``, a
hang or NaN later)."""

import dataclasses
import math
from datetime import timedelta

import numpy as np
import pytest
import torch
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hang_guard import no_hang
from sidar_torch import SidarConfig, SidarDataset, available_presets, load_config
from sidar_torch.config import (MAX_CAMERA_DISTANCE, MAX_GL_SIZE, MAX_LIGHT_INTENSITY, MAX_LIGHT_LEVEL, MAX_SAMPLE_BYTES, MAX_SCENE_EXTENT,
                                MAX_VIEWS)
from sidar_torch.config.memory import estimated_sample_bytes
from sidar_torch.sample import sequence_homographies
from sidar_torch.scene import sample_sequence

FIELDS = {f.name: f for f in dataclasses.fields(SidarConfig)}
NUMBER_TYPES = ("int", "float", "Range", "IntRange", "tuple[int, int]")


def test_every_number_field_has_finite_bounds_or_choices():
    for name, f in FIELDS.items():
        if str(f.type) in NUMBER_TYPES:
            assert "bounds" in f.metadata or "choices" in f.metadata, name
            assert all(map(math.isfinite, f.metadata.get("bounds", (0, 0)))), name


@pytest.mark.parametrize("field, value", [
    ("area_light_size", 1e300),  # spun forever in scene.kinds._covering_emitters
    ("light_xy", 1e307), ("light_height", (1e307, 1e307)),  # the same
    ("camera_height", (1e20, 1e20)),  # NaN homographies
    ("n_views", 10**127),  # accepted, then a hang
    ("image_size", (16384, 16384)),  # 17 GB and a failure after 185 s
    ("occluder_xy", 1e308),  # OverflowError
    ("camera_xy", 1.79e308), ("camera_xy", 1.8e308),  # LinAlgError; 1.8e308 is inf
    ("occluder_height", (1e300, 1e300)),  # pyrender's "zfar must be > 0"
    ("camera_xy", 10**400),  # OverflowError converting to float
    ("image_size", torch.tensor(5)), ("fov_deg", torch.tensor(50.0)), ("n_lights", np.array(2)),  # TypeError
    ("light_types", [["spot"]]), ("occluder_shapes", [{"a": 1}]),  # unhashable type
    ("shadow_filter", np.array(["tent", "bilinear"])),  # ambiguous truth value
    ("shadow_map_size", 16384),  # 16 shadow maps of 1.5 GiB
    ("image_size", iter([96, 128])),  # an iterator: no length
])
def test_the_issues_values_are_value_errors_naming_the_field(field, value):
    with pytest.raises(ValueError, match=f"config fields? .*'{field}'"):
        load_config("misaligned", **{field: value})


def test_negative_zero_is_zero():
    """Found by the fuzz below: ``ambient=(0, -0.0)`` passed and numpy's uniform raised "high - low < 0"."""
    config = load_config("misaligned", camera_xy=-0.0, ambient=(0, -0.0), max_tilt_deg=0)
    assert math.copysign(1, config.camera_xy) == 1 and math.copysign(1, config.ambient[1]) == 1
    assert_scene_is_finite(config)


def test_the_memory_estimate_keeps_the_defaults_and_the_largest_counts_within_the_budget():
    assert estimated_sample_bytes(load_config()) < MAX_SAMPLE_BYTES / 32  # about 0.08 GiB
    assert load_config(n_views=MAX_VIEWS, image_size=(64, 64)).n_views == MAX_VIEWS
    assert load_config(image_size=(MAX_GL_SIZE, 16), n_views=2).image_size == (MAX_GL_SIZE, 16)
    with pytest.raises(ValueError, match="'image_size', 'n_views' and 'shadow_map_size': a sample of 6 views of "
                                         "4096 x 4096 .* needs about 4.88 GiB"):
        load_config(image_size=(4096, 4096))


# --- fuzz: any value into any field of any preset ----------------------------------------------------

SPECIAL_NUMBERS = [0, -0.0, -1, 1, 2, 3, 0.5, 1e-300, 1e300, 1e307, 1.79e308, math.inf, -math.inf, math.nan, 10**400,
                   -10**400, 2**63, 2**64 + 1, 10**127]
NUMBERS = st.one_of(st.integers(), st.floats(), st.sampled_from(SPECIAL_NUMBERS))
WORDS = sorted({w for f in FIELDS.values() for w in f.metadata.get("choices", ()) if isinstance(w, str)})
TENSORS = st.one_of(
    st.builds(torch.tensor, st.floats(width=32)), st.builds(torch.tensor, st.integers(-2**63, 2**63 - 1)),
    st.builds(torch.tensor, st.booleans()), st.builds(torch.tensor, st.lists(st.floats(width=32), max_size=3)),
    st.builds(np.array, st.floats()), st.builds(np.array, st.lists(st.integers(-1000, 1000), max_size=3)),
    st.builds(np.float32, st.floats(width=32)), st.builds(np.int64, st.integers(-2**63, 2**63 - 1)))
SCALARS = st.one_of(st.none(), st.booleans(), NUMBERS, st.text(max_size=6), st.sampled_from(WORDS), TENSORS)
VALUES = st.recursive(SCALARS, lambda inner: st.lists(inner, max_size=3) | st.tuples(inner, inner), max_leaves=6)


def near_bounds(f: dataclasses.Field) -> st.SearchStrategy:
    """Values at, inside and just outside field ``f``'s bounds (what a fuzz needs to reach accepted configs)."""
    if "bounds" not in f.metadata:
        return st.sampled_from(list(f.metadata.get("choices", ())) or [f.default])
    lo, hi = f.metadata["bounds"]
    edges = [lo, hi, (lo + hi) / 2, lo + (hi - lo) * 1e-3, hi * (1 + 1e-9) + 1e-9, lo - 1e-9, hi * 2]
    number = st.sampled_from(edges).map(lambda x: int(x) if str(f.type) in ("int", "IntRange", "tuple[int, int]")
                                        and float(x).is_integer() else x)
    return number if str(f.type) in ("int", "float") else st.tuples(number, number).map(
        lambda pair: tuple(sorted(pair)) if str(f.type) != "tuple[int, int]" else pair)


def assert_scene_is_finite(config: SidarConfig) -> None:
    """Draw one sample's scenes (no rendering) and check every number of them is finite."""
    sequence = sample_sequence(config, np.random.default_rng(0))
    arrays = [a for view in sequence.views for a in (
        view.camera.K, view.camera.R, view.camera.t, view.ambient,
        *(x for light in view.lights for x in (light.emitters, light.intensity, light.inner_cone, light.outer_cone)),
        *(x for occluder in view.occluders for x in (occluder.position, occluder.scale)))]
    assert all(np.isfinite(a).all() for a in arrays)
    if config.n_views <= 8:
        homographies, error = sequence_homographies(sequence)
        assert torch.isfinite(homographies).all() and math.isfinite(error)


@settings(max_examples=400, deadline=timedelta(seconds=10), derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(st.data())
def test_fuzzed_values_give_a_config_that_samples_or_a_value_error_naming_the_field(data):
    """Any value (numbers huge, inf, NaN; words; nested lists; tensors and arrays; None) in any field
    of any preset: a config whose scene can be drawn with finite numbers, or a ``ValueError`` naming
    the field (a wrong type included). Derandomised: the same 400 examples each run, a few seconds."""
    preset = data.draw(st.sampled_from(available_presets()), label="preset")
    field = data.draw(st.sampled_from(sorted(FIELDS)), label="field")
    value = data.draw(st.one_of(VALUES, near_bounds(FIELDS[field])), label="value")
    with no_hang(10):
        try:
            config = load_config(preset, **{field: value})
        except ValueError as error:
            assert f"'{field}'" in str(error), error
            return
        try:
            assert_scene_is_finite(config)
        except ValueError as error:  # min_coverage / min_overlap no camera meets: said when drawn
            assert field in ("min_coverage", "min_overlap") and f"'{field}'" in str(error), error


# --- the bounds render ------------------------------------------------------------------------------

FAR, TINY = MAX_SCENE_EXTENT, 1e-4
EXTREMES = {
    "everything far and bright": dict(
        camera_xy=MAX_CAMERA_DISTANCE, camera_height=(MAX_CAMERA_DISTANCE,) * 2, fov_deg=(1, 1),
        light_xy=FAR, light_height=(FAR, FAR), area_light_size=FAR, occluder_xy=FAR, occluder_height=(FAR, FAR),
        occluder_size=(FAR, FAR), light_irradiance=(MAX_LIGHT_LEVEL,) * 2, spot_irradiance=(MAX_LIGHT_LEVEL,) * 2,
        area_irradiance=(MAX_LIGHT_LEVEL,) * 2, ambient=(MAX_LIGHT_LEVEL,) * 2, n_lights=(6, 6), n_occluders=(16, 16),
        spot_cone_deg=(114, 114), area_spread_deg=(1, 1)),
    "everything near and dim": dict(
        camera_xy=0.0, camera_height=(1e-3, 1e-3), fov_deg=(170, 170), light_xy=0.0, light_height=(1e-3, 1e-3),
        area_light_size=TINY, occluder_xy=0.0, occluder_height=(0.0, 0.0), occluder_size=(TINY, TINY),
        light_irradiance=(0, 0), spot_irradiance=(0, 0), area_irradiance=(0, 0), ambient=(0, 0), n_lights=(8, 8),
        light_types=("spot", "point"), n_occluders=(16, 16), spot_cone_deg=(1, 1), spot_intensity=(0, TINY)),
    "grazing, lights and occluders at the box's edge": dict(
        camera_xy=MAX_CAMERA_DISTANCE, camera_height=(1e-3, 1e-3), fov_deg=(1, 170), light_xy=FAR,
        light_height=(1e-3, FAR), occluder_xy=FAR, occluder_height=(0.0, FAR), area_light_samples=24, n_lights=(1, 1),
        light_types=("area",), focal_uniform=True, area_intensity=(MAX_LIGHT_INTENSITY,) * 2),
    "effects at their bounds": dict(
        background="view", background_level=(1, 1), exposure_jitter=True, exposure_stops=(8, 8), gamma=(10, 10),
        sensor_noise=True, read_noise=(1, 1), shot_noise=(1, 1), jpeg=True, jpeg_quality=(1, 1),
        mesh_error_px=float(MAX_GL_SIZE), mask_min_opacity=1.0, opacity_output=True),
    "the longest side, one pixel high": dict(image_size=(1, MAX_GL_SIZE), antialias=4),
}


@pytest.mark.gl
@pytest.mark.parametrize("name", EXTREMES)
def test_configs_at_the_bounds_render_finite_samples_without_hanging(name):
    """One sample of each extreme at 2 views of 24 x 32 pixels (shadow maps of 64 texels: the largest,
    16384, would allocate 1.5 GiB per map; the largest sizes and view counts are checked against the
    memory estimate instead)."""
    config = load_config("misaligned", **{"image_size": (24, 32), "n_views": 2, "shadow_map_size": 64,
                                          **EXTREMES[name]})
    with no_hang(60):
        assert_sample_is_finite(SidarDataset(config=config, seed=1).sample(0))


def assert_sample_is_finite(sample: dict) -> None:
    for key, value in sample.items():
        if isinstance(value, torch.Tensor):
            assert torch.isfinite(value).all(), key
    assert sample["images"].min() >= 0 and sample["images"].max() <= 1
    assert math.isfinite(sample["homography_error"])


@pytest.mark.gl
def test_the_most_views_render_without_hanging():
    """256 views of 4 x 4 pixels: about 10 s (the 65536 homographies and their check dominate)."""
    config = load_config("ambient", image_size=(4, 4), n_views=MAX_VIEWS, shadow_map_size=16)
    with no_hang(120):
        sample = SidarDataset(config=config, seed=1).sample(0)
    assert_sample_is_finite(sample)
    assert sample["homographies"].shape == (MAX_VIEWS, MAX_VIEWS, 3, 3)
