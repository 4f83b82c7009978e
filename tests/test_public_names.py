"""The names users import from the package's top (``from sidar_torch import ...``), unchanged by where
their modules live; and the submodules users import by path in the README and the docs."""

import importlib

import sidar_torch

PUBLIC = ["ExportedDataset", "SidarAugment", "SidarConfig", "SidarDataset", "SidarStep", "available_presets", "evaluate",
          "export_dataset", "flow", "homography_pairs", "load_config", "undistort"]
"""``from sidar_torch import *``, as it was before the package's modules were grouped into floors."""

SUBMODULES = ["sidar_torch.config", "sidar_torch.geometry", "sidar_torch.io", "sidar_torch.paintings",
              "sidar_torch.deep_homography", "sidar_torch.sample"]


def test_the_top_level_names_are_the_public_ones():
    assert sorted(sidar_torch.__all__) == sorted(PUBLIC)
    namespace = {}
    exec("from sidar_torch import *", namespace)
    assert sorted(name for name in namespace if not name.startswith("__")) == sorted(PUBLIC)
    assert isinstance(sidar_torch.__version__, str)


def test_each_public_name_is_the_object_its_module_defines():
    for name in PUBLIC:
        value = getattr(sidar_torch, name)
        home = importlib.import_module(value.__module__)
        assert getattr(home, name) is value, name


def test_the_submodules_users_import_by_path_import():
    for name in SUBMODULES:
        assert importlib.import_module(name).__name__ == name
