import dataclasses
from pathlib import Path

import pytest

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
    ("n_occluders", (-1, 2)), ("fov_deg", (200, 210)), ("fov_deg", (60, "wide")), ("max_tilt_deg", 90),
    ("light_types", ("laser",)), ("light_types", "spot"), ("occluder_shapes", ()),
    ("shadow_map_size", 1000), ("ambient", (float("nan"), 1.0)), ("aligned", "yes"),
    ("n_views", 2.5), ("plane_roughness", (0.5, 2.0)), ("light_types", {"spot", "point"}),
    ("spot_cone_deg", (120, 120)),
    ("image_size", (64, 0)), ("n_views", -3), ("camera_height", (1.0, 0.5)), ("light_irradiance", (2.0, 1.0)),
    ("min_coverage", 1.5), ("min_overlap", -0.1), ("on_bad_image", "ignore"), ("on_bad_image", None),
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


CONFIGS = Path(__file__).resolve().parent.parent / "configs"


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
