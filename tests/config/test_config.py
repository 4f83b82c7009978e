import dataclasses
from pathlib import Path

import numpy as np
import pytest
import torch

import sidar_torch.config
from sidar_torch import SidarConfig, available_presets, load_config

CORE_PRESETS = ["misaligned", "aligned", "ambient", "shadows_only", "occlusions_only"]


def test_core_presets_exist_and_say_what_they_mean():
    assert set(CORE_PRESETS) <= set(available_presets())
    assert load_config("misaligned") == load_config()
    assert load_config("aligned").aligned
    ambient = load_config("ambient")
    assert ambient.n_lights == (0, 0) and ambient.n_occluders == (0, 0)
    assert not load_config("shadows_only").occluders_visible and load_config("shadows_only").shadows
    assert not load_config("occlusions_only").shadows and load_config("occlusions_only").n_occluders[0] >= 1


def test_keyword_overrides_replace_preset_values():
    cfg = load_config("misaligned", image_size=(384, 512), n_views=6, n_lights=(1, 2), n_occluders=[0, 1],
                      fov_deg=(30, 40), max_tilt_deg=45)
    assert cfg.image_size == (384, 512) and cfg.n_views == 6
    assert cfg.n_lights == (1, 2) and cfg.n_occluders == (0, 1)  # lists become tuples
    assert cfg.fov_deg == (30.0, 40.0) and cfg.max_tilt_deg == 45.0
    assert load_config(cfg, n_views=2).n_views == 2


@pytest.mark.parametrize("field, value", [
    ("image_size", (0, 64)), ("image_size", (64,)), ("n_views", 0), ("n_lights", (3, 1)),
    ("n_occluders", (-1, 2)), ("fov_deg", (200, 210)), ("fov_deg", (60, "wide")), ("max_tilt_deg", 90.5),
    ("light_types", ("laser",)), ("light_types", "spot"), ("occluder_shapes", ()),
    ("shadow_map_size", 1000), ("ambient", (float("nan"), 1.0)), ("aligned", "yes"),
    ("n_views", 2.5), ("plane_roughness", (0.5, 2.0)), ("light_types", {"spot", "point"}),
    ("spot_cone_deg", (120, 120)),
    ("image_size", (64, 0)), ("n_views", -3), ("camera_height", (1.0, 0.5)), ("light_irradiance", (2.0, 1.0)),
    ("min_coverage", 1.5), ("min_overlap", -0.1), ("on_bad_image", "ignore"), ("on_bad_image", None),
    ("reference_height", (0.0, 1.0)), ("reference_height", (1e-4, 1e-4)), ("reference_height", (-1.0, 1.0)),
    ("light_radius", -0.01), ("light_radius", 1.0), ("light_radius", float("nan")),
])
def test_bad_values_raise_naming_the_field(field, value):
    with pytest.raises(ValueError, match=field):
        load_config("misaligned", **{field: value})


def test_unknown_fields_and_presets_are_rejected():
    with pytest.raises(ValueError, match="n_veiws"):
        load_config("misaligned", n_veiws=3)
    with pytest.raises(ValueError, match="n_veiws"):
        SidarConfig().replace(n_veiws=3)
    with pytest.raises(ValueError, match="not a preset"):
        load_config("no_such_preset")
    with pytest.raises(FileNotFoundError):
        load_config("/nonexistent/config.yaml")


def test_yaml_file_with_base_preset(tmp_path):
    path = tmp_path / "mine.yaml"
    path.write_text("base: aligned\nn_views: 4\nn_occluders: [2, 2]\n")
    cfg = load_config(path, image_size=(64, 64))
    assert cfg.aligned and cfg.n_views == 4 and cfg.n_occluders == (2, 2) and cfg.image_size == (64, 64)
    path.write_text("base: aligned\nn_view: 4\n")
    with pytest.raises(ValueError, match="n_view"):
        load_config(path)
    loop = tmp_path / "loop.yaml"
    loop.write_text("base: loop.yaml\n")
    with pytest.raises(ValueError, match="loops"):
        load_config(loop)


def test_on_bad_image_switch():
    assert SidarConfig().on_bad_image == "raise"
    assert load_config("misaligned", on_bad_image="skip").on_bad_image == "skip"


def test_too_many_shadowed_emitters_rejected():
    with pytest.raises(ValueError, match="area_light_samples"):
        SidarConfig(n_lights=(1, 8), area_light_samples=4)


CONFIGS = Path(__file__).resolve().parents[2] / "configs"


@pytest.mark.parametrize("path", sorted(CONFIGS.glob("*.yaml")), ids=lambda p: p.name)
def test_each_example_config_loads_and_changes_its_base(path):
    # configs/ holds user-facing examples that derive from a preset; the presets ship in the package.
    config = load_config(path)
    assert config != load_config("misaligned")
    assert path.stem not in available_presets()


def test_example_configs_say_what_the_readme_says():
    training = load_config(CONFIGS / "homography_training.yaml")
    assert training.image_size == (192, 256) and training.n_views == 4 and training.min_overlap == 0.3
    photos = load_config(CONFIGS / "own_photos.yaml")
    assert photos.image_size == (192, 256) and photos.on_bad_image == "skip" and photos.opacity_output
    readme = (CONFIGS / "README.md").read_text()
    assert all(f"`{p.name}`" in readme for p in CONFIGS.glob("*.yaml"))


def test_presets_ship_inside_the_package_not_in_configs():
    from sidar_torch.config import PRESET_DIR

    assert PRESET_DIR.parent == Path(sidar_torch.config.__file__).parent
    assert sorted(p.stem for p in PRESET_DIR.glob("*.yaml")) == available_presets()
    assert set(CORE_PRESETS) | {"paper_misaligned", "paper_aligned"} <= set(available_presets())
    assert not {p.stem for p in CONFIGS.glob("*.yaml")} & set(available_presets())


def test_field_meanings_are_metadata():
    from sidar_torch.config import field_meaning

    for f in dataclasses.fields(SidarConfig):
        assert f.metadata["meaning"] == field_meaning(f.name) and f.metadata["meaning"].endswith("."), f.name
    assert "(H, W)" in field_meaning("image_size")


# Issue 13 item 3: numbers as users pass them.
@pytest.mark.parametrize("overrides, expected", [
    ({"n_views": np.int64(3)}, {"n_views": 3}),
    ({"n_views": np.uint8(3)}, {"n_views": 3}),
    ({"image_size": (np.int32(192), 256)}, {"image_size": (192, 256)}),
    ({"image_size": (torch.tensor(192), torch.tensor(256, dtype=torch.int16))}, {"image_size": (192, 256)}),
    ({"image_size": torch.tensor([192, 256])}, {"image_size": (192, 256)}),
    ({"image_size": np.array([192, 256])}, {"image_size": (192, 256)}),
    ({"fov_deg": (np.float32(40), 60)}, {"fov_deg": (40.0, 60.0)}),
    ({"fov_deg": (np.float16(40), torch.tensor(60.0, dtype=torch.float64))}, {"fov_deg": (40.0, 60.0)}),
    ({"max_tilt_deg": np.float64(45), "n_lights": (np.int16(1), np.int64(2))}, {"max_tilt_deg": 45.0, "n_lights": (1, 2)}),
    ({"shadow_map_size": torch.tensor(512), "mask_min_opacity": torch.tensor(0.5)},
     {"shadow_map_size": 512, "mask_min_opacity": 0.5}),
])
def test_numpy_and_torch_scalars_are_accepted_as_plain_numbers(overrides, expected):
    config = load_config("misaligned", **overrides)
    for name, value in expected.items():
        got = getattr(config, name)
        assert got == value and type(got) is type(value), (name, got)
        if isinstance(value, tuple):
            assert [type(v) for v in got] == [type(v) for v in value], (name, got)
    assert config == load_config("misaligned", **expected)  # the same config, hashable and comparable


@pytest.mark.parametrize("field, value, message", [
    ("n_views", np.True_, "expected a number"),
    ("n_views", torch.tensor(True), "expected a number"),
    ("n_views", True, "expected a number"),
    ("n_views", np.float32(2.5), "expected an integer"),
    ("n_views", torch.tensor([3, 4]), "expected a number"),
    ("fov_deg", (np.float32(40), np.nan), "finite"),
    ("image_size", (np.int32(192), np.complex64(256)), "expected a number"),
])
def test_bools_non_integers_and_arrays_are_still_refused(field, value, message):
    with pytest.raises(ValueError, match=f"'{field}'.*{message}"):
        load_config("misaligned", **{field: value})


def test_as_int_and_as_float_are_the_one_conversion_other_layers_reuse():
    from sidar_torch.config import as_float, as_int

    assert as_int("count", np.int64(3)) == 3 and type(as_int("count", torch.tensor(3))) is int
    assert as_int("count", 4.0) == 4
    assert as_float("scale", np.float32(0.5)) == 0.5 and type(as_float("scale", torch.tensor(2))) is float
    with pytest.raises(ValueError, match="^count: expected a number, got True"):
        as_int("count", True)
    with pytest.raises(ValueError, match="^count: expected an integer"):
        as_int("count", float("inf"))
    with pytest.raises(ValueError, match="^scale: expected a finite number"):
        as_float("scale", np.float64("inf"))


# Issue 13 item 4: limits found when the config is made; YAML errors name the file and line;
# unknown fields suggest the closest names.
@pytest.mark.parametrize("field, value", [
    ("image_size", (64, 16385)), ("image_size", (16385, 64)), ("shadow_map_size", 32768),
])
def test_sizes_beyond_the_gl_limit_are_refused_naming_the_field_and_the_limit(field, value):
    with pytest.raises(ValueError, match=f"config field '{field}'.*16384"):
        load_config("misaligned", **{field: value})
    # One shadowed emitter of 16384^2 texels (1.5 GiB) fits a sample's memory; the default lights' 16 would not.
    one_light = dict(n_lights=(1, 1), light_types=("spot",))
    config = load_config("misaligned", image_size=(16, 16384), shadow_map_size=16384, **one_light)
    assert config.shadow_map_size == 16384


def test_the_gl_limit_is_said_in_the_fields_meaning():
    from sidar_torch.config import MAX_GL_SIZE, field_meaning

    assert MAX_GL_SIZE == 16384
    assert "16384" in field_meaning("image_size") and "16384" in field_meaning("shadow_map_size")


def test_malformed_yaml_names_the_file_and_line(tmp_path):
    path = tmp_path / "broken.yaml"
    path.write_text("base: misaligned\nn_views: 3\nimage_size: [96, 128\nshadows: false\n")
    with pytest.raises(ValueError, match=r"broken\.yaml', line 4, column \d+: malformed YAML") as error:
        load_config(path)
    assert "<unicode string>" not in str(error.value)
    path.write_text("base: misaligned\n- n_views: 3\n")
    with pytest.raises(ValueError, match=r"broken\.yaml', line 2, column 1: malformed YAML"):
        load_config(path)


def test_unknown_fields_suggest_the_closest_names_not_all_of_them(tmp_path):
    with pytest.raises(ValueError, match=r"'n_veiws' \(did you mean 'n_views'\?\)") as error:
        load_config("misaligned", n_veiws=3)
    assert "light_irradiance" not in str(error.value)  # no list of every field
    with pytest.raises(ValueError, match=r"'shadow_map' \(did you mean 'shadow_map_size'"):
        SidarConfig().replace(shadow_map=512)
    path = tmp_path / "mine.yaml"
    path.write_text("base: misaligned\nimage_sise: [96, 128]\nzzz: 1\n")
    with pytest.raises(ValueError, match=r"mine\.yaml.*'image_sise' \(did you mean 'image_size'( or '\w+')?\?\), 'zzz';"):
        load_config(path)


# Issue 13 item 7: sizes read (H, W); a 3-element image_size is not a (low, high) range.
def test_a_three_element_image_size_says_it_expects_h_w():
    with pytest.raises(ValueError, match=r"'image_size': expected 2 values \(H, W\), got 3") as error:
        load_config("misaligned", image_size=(96, 128, 3))
    assert "low, high" not in str(error.value)
    with pytest.raises(ValueError, match=r"'fov_deg': expected 2 values \(low, high\)"):
        load_config("misaligned", fov_deg=(40, 50, 60))


# Issue 13 item 8: an infinite end of a range cannot be drawn from uniformly (numpy's uniform raises
# OverflowError); the error says why. Issue 25 item 4: every range has a finite upper bound, which
# the schema shows.
@pytest.mark.parametrize("field", ["camera_height", "light_height", "ambient", "occluder_size", "spot_irradiance"])
def test_an_infinite_range_end_is_refused_saying_why_and_the_schema_shows_the_finite_bound(field):
    from sidar_torch.config.schema import schema_rows

    with pytest.raises(ValueError, match=f"'{field}': expected finite numbers .*drawn uniformly"):
        load_config("misaligned", **{field: [1, float("inf")]})
    (row,) = [r for r in schema_rows() if r["name"] == field]
    highest = SidarConfig.__dataclass_fields__[field].metadata["bounds"][1]
    assert "inf" not in row["allowed"] and row["allowed"].endswith(f"<= {highest:g}"), row
    assert getattr(load_config("misaligned", **{field: [1, highest]}), field) == (1, highest)
    with pytest.raises(ValueError, match=f"'{field}': expected a range .* <= {highest:g}, got \\(1.0, {highest * 2:g}"):
        load_config("misaligned", **{field: [1, highest * 2]})


# Issue 25 item 6: a YAML file nested thousands deep or not text at all is a ValueError naming the file.
def test_deeply_nested_and_binary_yaml_files_are_value_errors_naming_the_file(tmp_path):
    deep = tmp_path / "deep.yaml"
    deep.write_text("n_views: " + "[" * 5000 + "]" * 5000 + "\n")
    with pytest.raises(ValueError, match=r"deep\.yaml': YAML nested too deeply to parse"):
        load_config(deep)
    binary = tmp_path / "binary.yaml"
    binary.write_bytes(b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR\xff\xfe")
    with pytest.raises(ValueError, match=r"binary\.yaml': not UTF-8 text \(byte 0x89 at offset 0\)"):
        load_config(binary)
    nul = tmp_path / "nul.yaml"
    nul.write_bytes(b"n_views: 3\x00\n")
    with pytest.raises(ValueError, match=r"nul\.yaml': malformed YAML"):
        load_config(nul)


# Issue 20 item 6: a wrong preset name gets the closest names.
def test_a_wrong_preset_name_suggests_the_closest_presets():
    with pytest.raises(ValueError, match=r"'misalinged': not a preset \(did you mean 'misaligned'") as error:
        load_config("misalinged")
    assert "paper_aligned" in str(error.value)  # and lists them all, as before
    with pytest.raises(ValueError, match=r"'zzz': not a preset nor a YAML path; the presets are aligned, "):
        load_config("zzz")


def test_yaml_reads_exponent_floats_as_numbers(tmp_path):
    """PyYAML (YAML 1.1) reads ``1e-3`` as a string; config files and ``--set`` read it as YAML 1.2 does."""
    path = tmp_path / "mine.yaml"
    path.write_text("base: misaligned\ncamera_height: [1e-3, 2E0]\narea_light_size: 5e-2\n")
    config = load_config(path)
    assert config.camera_height == (0.001, 2.0) and config.area_light_size == 0.05
