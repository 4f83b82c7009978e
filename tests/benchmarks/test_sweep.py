"""The speed-against-error sweep on tiny settings: structure, pixel alignment of supersampling and
that larger shadow maps come closer to the reference; never speed (that is what
``python -m benchmarks.sweep`` prints)."""

import json
import math
from dataclasses import replace

import numpy as np
import pytest
from PIL import Image

from benchmarks import sweep
from benchmarks.sweep import main
from sidar_torch import load_config
from sidar_torch.data.dataset import SidarDataset
from benchmarks.metrics import speckle_paintings
from sidar_torch.render import RenderSettings, SceneRenderer

from conftest import SMALL

pytestmark = [pytest.mark.gl, pytest.mark.slow]  # renders a tiny sweep (a module fixture); slow

TINY = sweep.SweepSettings(sizes=(SMALL,), shadow_map_sizes=(32, 128, 512), supersampling=(1,),
                           mesh_errors=(1.0,), base_shadow_map_size=128, reference=(2048, 1), scenes=2,
                           residual_samples=1, label_samples=1, preset="shadows_only", n_views=3)


@pytest.fixture(scope="module")
def report():
    return sweep.run_sweep(TINY, log=lambda line: None)


def test_report_structure_and_outputs(report, tmp_path):
    rows = report["rows"]
    knobs = [(r["shadow_map_size"], r["shadow_frustum"], r["mesh_detail"], r["texture_filter"], r["shadow_filter"])
             for r in rows]
    assert [r["antialias"] for r in rows] == [1] * 14 + [4, 1]
    grid = [(m, f, "fixed", "trilinear", sf) for sf in ("tent", "bilinear") for f in ("cone", "fitted")
            for m in (32, 128, 512)]
    assert knobs == grid + [(128, "fitted", "<= 1 px", "trilinear", "tent"), (128, "fitted", "fixed", "bilinear", "tent"),
                            (128, "fitted", "fixed", "trilinear", "tent"), (2048, "fitted", "finest", "trilinear", "tent")]
    assert all(r["size"] == "96x128" and r["supersampling"] == 1 and r["ms_per_view"] > 0 for r in rows)
    assert [r["reference"] for r in rows] == [False] * 15 + [True]
    assert math.isinf(rows[-1]["image_psnr_db"]) and not rows[-1]["pareto"]
    assert any(r["pareto"] for r in rows[:-1])
    assert [r["supersampling"] for r in report["residuals"]] == [1]
    assert report["residuals"][0]["patches"] > 0 and report["residuals"][0]["max_px"] < 0.5
    assert report["labels"][0]["min_psnr_db"] >= 45
    paths = sweep.write_outputs(report, tmp_path / "out")
    assert "| 96x128 | 512 | fitted | tent | 1x | fixed | trilinear | 1x |" in paths["md"].read_text()
    assert json.loads(paths["json"].read_text())["rows"][0]["shadow_map_size"] == 32
    with Image.open(paths["png"]) as image:
        assert image.size == (900, 600)


def test_larger_shadow_maps_come_closer_to_the_reference(report):
    """The scenes have shadows (shadows_only: invisible occluders casting them), so the coarsest
    map must be measurably worse, and no larger map worse than a smaller one, with either
    frustum; at each size the fitted frustum comes closer than the cone's."""
    cone, fitted = ([r["image_psnr_db"] for r in report["rows"][k:k + 3]] for k in (0, 3))
    for values in (cone, fitted):
        assert all(math.isfinite(v) for v in values)
        assert values == sorted(values), values
        assert values[-1] > values[0] + 1.0, values
    assert all(f > c for f, c in zip(fitted, cone)), (cone, fitted)


def test_pareto_front():
    rows = [{"ms_per_view": 1.0, "image_psnr_db": 30.0}, {"ms_per_view": 2.0, "image_psnr_db": 29.0},
            {"ms_per_view": 2.0, "image_psnr_db": 35.0}, {"ms_per_view": 3.0, "image_psnr_db": math.inf},
            {"ms_per_view": 2.5, "image_psnr_db": 35.0}]
    assert sweep.pareto_front(rows) == [0, 2]


def test_supersampled_views_keep_pixel_centres():
    """An ambient scene drawn at 2x and area-averaged matches the 1x draw; a camera off by half
    a 2x pixel does measurably worse, so the check can fail."""
    config = load_config("ambient", image_size=SMALL, n_views=3)
    dataset = SidarDataset(speckle_paintings(1, SMALL, 0, scale=3.0), config, seed=0)
    sequence, painting = dataset.scene(0), dataset.source.painting(0, SMALL)
    big = sweep.supersampled_sequence(sequence, 2)
    assert big.image_size == (2 * SMALL[0], 2 * SMALL[1])
    np.testing.assert_allclose(big.views[1].camera.K[:2, 2], 2 * sequence.views[1].camera.K[:2, 2] + 0.5)
    one, two = SceneRenderer(RenderSettings(SMALL, 64)), SceneRenderer(RenderSettings(big.image_size, 64))
    try:
        v1, m1 = sweep.render_views(one, sequence, painting, 1)
        v2, m2 = sweep.render_views(two, sequence, painting, 2)
        assert v2.shape == v1.shape and m2.shape == m1.shape
        seen = (1 - m1) * (1 - m2)

        def masked_psnr(a, b):
            return 10 * math.log10(3 * float(seen.sum()) / float(((a - b) ** 2 * seen).sum()))

        shift = np.array([[1, 0, -0.5], [0, 1, -0.5], [0, 0, 1.0]])  # half a 2x pixel up and left
        with pytest.MonkeyPatch.context() as patch:
            patch.setattr(sweep, "supersampled_sequence", lambda s, f: replace(big, views=tuple(
                replace(v, camera=replace(v.camera, K=shift @ v.camera.K)) for v in big.views)))
            v3, _ = sweep.render_views(two, sequence, painting, 2)
        assert masked_psnr(v1, v2) > 40
        assert masked_psnr(v1, v2) > masked_psnr(v1, v3) + 5
    finally:
        one.close()
        two.close()


def test_cli_writes_the_three_files(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(sweep.SweepSettings, "quick", classmethod(
        lambda cls, **changes: replace(TINY, shadow_map_sizes=(64,), shadow_frusta=("cone",), mesh_errors=(),
                                       shadow_filters=("tent",), scenes=1, **changes)))
    main(["--quick", "--config", "shadows_only", "--set", "n_occluders=[1,1]", "--out-dir", str(tmp_path)])
    assert "| 96x128 | 64 | cone | tent | 1x | fixed | trilinear |" in capsys.readouterr().out
    assert {p.name for p in tmp_path.iterdir()} == {"sweep.md", "sweep.json", "sweep.png"}
    settings = json.loads((tmp_path / "sweep.json").read_text())["settings"]
    assert settings["preset"] == "shadows_only" and settings["overrides"] == {"n_occluders": [1, 1]}


def test_cli_overrides_reach_the_scenes_and_bad_ones_are_named():
    settings = sweep.SweepSettings(sizes=(SMALL,), preset="shadows_only", overrides={"n_occluders": (2, 2)})
    assert all(len(view.occluders) == 2 for view in sweep._dataset(settings, SMALL).scene(0).views)
    with pytest.raises(SystemExit, match="n_veiws"):
        main(["--quick", "--set", "n_veiws=2"])
    with pytest.raises(SystemExit, match="image_size"):
        main(["--quick", "--set", "image_size=[8,8]"])
    with pytest.raises(SystemExit, match="--reference: expected MAPxS"):
        main(["--quick", "--reference", "4096"])


def test_shadow_filter_is_crossed_with_map_sizes_and_frusta(report):
    rows = [r for r in report["rows"] if r["shadow_filter"] == "bilinear"]
    assert sorted((r["shadow_map_size"], r["shadow_frustum"]) for r in rows) == sorted(
        (m, f) for m in TINY.shadow_map_sizes for f in TINY.shadow_frusta)
    assert all(math.isfinite(r["image_psnr_db"]) for r in rows)
def test_antialiasing_comes_closer_to_a_supersampled_reference():
    """Against a 2 x 2 supersampled reference the multisampled colour pass must gain: its edges are
    blended as the reference's average blends them (the occluders are visible here)."""
    settings = replace(TINY, only="antialias", reference=(512, 2), preset="misaligned", scenes=2)
    base, msaa, reference = sweep.run_sweep(settings, log=lambda line: None)["rows"]
    assert (base["antialias"], msaa["antialias"], reference["reference"]) == (1, 4, True)
    assert msaa["image_psnr_db"] > base["image_psnr_db"] + 1.0, (base, msaa)


def test_only_one_knob_measures_the_base_its_variations_and_the_reference():
    settings = replace(TINY, only="antialias").settings()
    assert [(s.shadow_map_size, s.antialias) for s in settings] == [(128, 1), (128, 4), (2048, 1)]
    with pytest.raises(ValueError, match="only"):
        replace(TINY, only="exposure")
    with pytest.raises(ValueError, match="antialias"):
        replace(TINY, antialias=(3,))


def test_bad_settings_name_the_field():
    with pytest.raises(ValueError, match="shadow_map_sizes"):
        sweep.SweepSettings(shadow_map_sizes=(300,))
    with pytest.raises(ValueError, match="supersampling"):
        sweep.SweepSettings(supersampling=(0,))
    with pytest.raises(ValueError, match="shadow_frusta"):
        sweep.SweepSettings(shadow_frusta=("tight",))
    with pytest.raises(ValueError, match="texture_filters"):
        sweep.SweepSettings(texture_filters=("nearest",))
    with pytest.raises(ValueError, match="shadow_filters"):
        sweep.SweepSettings(shadow_filters=("box",))
    with pytest.raises(ValueError, match="mesh_errors"):
        sweep.SweepSettings(mesh_errors=(-1.0,))
