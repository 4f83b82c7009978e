"""Smoke runs of the examples' ``--quick`` modes, checking that what they print makes sense."""

import importlib.util
import math
import re
import sys
from pathlib import Path

import torch
import pytest

pytestmark = pytest.mark.gl  # renders

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


def load(name):
    spec = importlib.util.spec_from_file_location(f"example_{name}", EXAMPLES / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up there
    spec.loader.exec_module(module)
    return module


def test_train_homography_quick(capsys):
    results = load("train_homography").main(["--quick"])
    assert set(results) == {"network", "identity"}
    assert all(math.isfinite(error) and error >= 0 for error in results.values())
    # corners move by U(-8, 8) per coordinate: standing still is off by about 6 px per corner
    assert 3 < results["identity"] < 9
    out = capsys.readouterr().out
    assert "step 3: loss" in out and "held-out MACE: network" in out


def test_restoration_batch_quick(capsys):
    results = load("restoration_batch").main(["--quick"])
    assert all(5 < value < 60 for value in results.values())
    out = capsys.readouterr().out
    assert "network input (views and masks stacked) (2, 12, 48, 64) -> target (2, 3, 48, 64)" in out
    assert float(re.search(r"largest \|H - I\| (\S+)", out)[1]) < 1e-9  # the aligned preset: identities


def test_dense_correspondence_quick(capsys):
    module = load("dense_correspondence")
    results = module.main(["--quick"])
    assert 0 < results["visible fraction"] < 1
    assert results["forward-backward error, px (median; backward flow read bilinearly)"] < 0.1
    assert results["colour difference along the flow"] < results["colour difference without the flow"]
    assert "flow 1 -> 2 (2, 2, 48, 64), visible (2, 1, 48, 64)" in capsys.readouterr().out


def test_flow_of_a_known_homography():
    """A pure translation by (3, -2) px with no occlusion: the flow is (3, -2) everywhere and visible
    wherever the moved pixel stays inside the image."""
    module = load("dense_correspondence")
    H = torch.eye(3).repeat(1, 2, 2, 1, 1)
    H[0, 0, 1, :2, 2] = torch.tensor([3.0, -2.0])
    masks = torch.zeros(1, 2, 1, 8, 10)
    flow, visible = module.flow_and_visibility(H, masks, 0, 1)
    assert torch.allclose(flow, torch.tensor([3.0, -2.0]).view(1, 2, 1, 1).expand(1, 2, 8, 10))
    expected = torch.zeros(8, 10, dtype=torch.bool)
    expected[2:, :7] = True
    assert torch.equal(visible[0, 0], expected)
    masks[0, 1, 0, 5, 5] = 1  # view 1 hides pixel (u=5, v=5), which view-0 pixel (2, 7) lands on
    assert not module.flow_and_visibility(H, masks, 0, 1)[1][0, 0, 7, 2]


def test_shadow_removal_quick(capsys):
    results = load("shadow_removal").main(["--quick"])
    assert set(results) == {"trained network", "do nothing (the view itself)"}
    baseline = results["do nothing (the view itself)"]
    # Shadowed pixels differ from their shadow-free targets; elsewhere the view is (nearly) its own target.
    assert baseline["shadowed painting pixels"] > 5 * baseline["all pixels"] > 0
    assert all(math.isfinite(v) for row in results.values() for v in row.values())
    assert "| trained network |" in capsys.readouterr().out


def test_webdataset_stream_gives_the_exported_samples_shuffled(tmp_path, capsys):
    """Issue 34 item 7: the recipe streaming exported shards through webdataset (shuffle buffer, our
    sample dict). Each streamed sample is ExportedDataset's for its sequence, tensor for tensor."""
    pytest.importorskip("webdataset")
    from sidar_torch import ExportedDataset, SidarDataset, export_dataset, load_config

    module = load("webdataset_stream")
    config = load_config("misaligned", image_size=(24, 32), n_views=2, shadow_map_size=256)
    export_dataset(SidarDataset(config=config, seed=4), tmp_path, 7, shard_size=3, progress=False)
    read = ExportedDataset(tmp_path)
    streamed = list(module.stream(tmp_path, buffer=7, seed=1))
    order = [int(sample["index"]) for sample in streamed]
    assert sorted(order) == list(range(7)) and order != sorted(order)  # every sequence once, shuffled
    assert order == [int(s["index"]) for s in module.stream(tmp_path, buffer=7, seed=1)]  # the seed repeats it
    for sample in streamed:
        expected = read[read.indices.index(int(sample["index"]))]
        assert sample.keys() == expected.keys()
        for key, value in expected.items():
            assert torch.equal(torch.as_tensor(sample[key]), torch.as_tensor(value)), key
    batches = module.main(["--quick"])
    assert sorted(sum(batches, [])) == list(range(8)) and "images (4, 2, 3, 24, 32)" in capsys.readouterr().out


@pytest.mark.slow
def test_the_usage_page_quotes_what_dense_correspondence_prints():
    """Issue 34 item 7: docs/usage.md quoted a forward-backward error (0.0014 px) the example no longer
    printed (0.00156). The figures the page quotes are those of ``python examples/dense_correspondence.py``."""
    results = load("dense_correspondence").main([])
    page = (EXAMPLES.parent / "docs" / "usage.md").read_text()
    quoted = re.search(r"dense_correspondence.py` \(8 samples at 192x256\) prints the visible fraction\s+"
                       r"\((\S+)\) and the forward-backward error \((\S+) px median\)", page)
    assert quoted, "docs/usage.md no longer quotes the example's figures"
    assert quoted.groups() == (f"{results['visible fraction']:.4g}",
                               f"{results['forward-backward error, px (median; backward flow read bilinearly)']:.4g}")
