"""The benchmark and its timing instrumentation, on tiny settings: structure and sanity of the
figures, never speed (speed is what ``python -m sidar_torch bench`` prints)."""

import json
import math

import numpy as np
import pytest
import torch

from sidar_torch import bench, load_config
from sidar_torch.cli import main
from sidar_torch.sample import render_sample
from sidar_torch.scene import sample_sequence
from sidar_torch.timing import timed

from conftest import small_config, textured_painting

TINY = (48, 64)


def test_timed_adds_seconds_only_when_asked():
    calls = []
    with timed(None, "x", sync=lambda: calls.append(1)):
        pass
    assert calls == []
    timings = {}
    for _ in range(2):
        with timed(timings, "x", sync=lambda: calls.append(1)):
            pass
    assert calls == [1, 1] and set(timings) == {"x"} and timings["x"] > 0
    with pytest.raises(KeyError):
        with timed(timings, "y", sync=lambda: calls.append(1)):
            raise KeyError("boom")
    assert calls == [1, 1] and timings["y"] > 0  # failed block: timed, not synced


def test_timings_do_not_change_pixels():
    config = small_config()
    index = next(i for i in range(100)
                 if any(v.occluders for v in sample_sequence(config, np.random.default_rng([0, i])).views))
    sequence = sample_sequence(config, np.random.default_rng([0, index]))
    painting = textured_painting(config.image_size)
    plain = render_sample(sequence, painting, config, index)
    timings = {}
    measured = render_sample(sequence, painting, config, index, timings)
    for key in ("images", "masks", "label", "homographies", "K", "R", "t"):
        assert torch.equal(plain[key], measured[key]), key
    assert set(timings) == {"upload", "graph", "shadow", "colour", "mask", "label", "readback",
                            "homographies", "tensors"}
    assert all(v > 0 for v in timings.values())


def test_bench_report_structure_and_sanity():
    settings = bench.BenchSettings(presets=("misaligned",), sizes=(TINY,), workers=(0,), samples=2,
                                   kornia_images=2)
    report = bench.run_bench(settings, log=lambda line: None)
    json.dumps(report)  # plain data
    (run,) = report["runs"]
    assert (run["preset"], run["size"], run["views"], run["loaders"]) == ("misaligned", "64x48", 6, [])
    main_row = run["main"]
    total = main_row["seconds_per_sequence"]
    assert 0 < total < math.inf
    assert main_row["sequences_per_s"] == pytest.approx(1 / total)
    assert main_row["views_per_s"] == pytest.approx(6 / total)
    assert main_row["ms_per_view"] == pytest.approx(1e3 * total / 6)
    assert main_row["warmup_s"] > 0 and main_row["peak_mb"] > 0 and main_row["kornia_ratio"] > 0
    assert main_row["new_shadow_maps_mb"] >= 0 and math.isfinite(main_row["rss_growth_mb"])
    steps = main_row["steps_s"]
    assert set(steps) == {*bench.STEPS, "other"}
    for key in ("scene", "painting", "upload", "graph", "colour", "mask", "label", "readback", "homographies",
                "tensors"):
        assert steps[key] > 0, key
    assert steps["shadow"] >= 0
    assert sum(v for k, v in steps.items() if k != "other") <= 1.1 * total
    (kornia,) = report["kornia"]
    assert kornia["size"] == "64x48" and kornia["ms_per_image"] > 0
    assert main_row["kornia_ratio"] == pytest.approx(main_row["ms_per_view"] / kornia["ms_per_image"])
    assert len(report["targets"]) == 3  # time, kornia ratio, memory; no loader row: no scaling target
    assert all(isinstance(t["met"], bool) and t["measured"] for t in report["targets"])
    assert report["machine"]["cpus"] >= 1 and report["seconds"] > 0

    text = bench.format_report(report)
    assert "| misaligned | 64x48 | main |" in text
    assert text.count("| misaligned | 64x48 |") == 2  # throughput and time-per-step rows
    assert "| 64x48 |" in text.split("Kornia")[1]
    assert "## Targets" in text and "ratio" in text


def test_loader_rows_measure_the_samples_of_the_main_process():
    config = load_config("ambient", image_size=TINY, n_views=2)
    row = bench.measure_loader(config, workers=2, samples=3, seed=0)
    assert row["workers"] == 2 and row["samples"] == 4  # rounded up to a multiple of the workers
    assert row["sequences_per_s"] > 0 and row["views_per_s"] == pytest.approx(2 * row["sequences_per_s"])
    assert row["wall_sequences_per_s"] > 0 and row["warmup_s"] > 0 and row["peak_mb"] > 0


def test_settings_reject_bad_values():
    with pytest.raises(ValueError, match="samples"):
        bench.BenchSettings(samples=0)
    with pytest.raises(ValueError, match="workers"):
        bench.BenchSettings(workers=(-1,))
    with pytest.raises(ValueError, match="sizes"):
        bench.BenchSettings(sizes=((0, 64),))
    with pytest.raises(ValueError, match="image_size"):
        bench.BenchSettings(overrides={"image_size": [48, 64]})


def test_cli_prints_and_writes_the_table(tmp_path, capsys):
    md, js = tmp_path / "b" / "bench.md", tmp_path / "bench.json"
    main(["bench", "--presets", "ambient", "--sizes", "64x48", "--workers", "0", "--samples", "1",
          "--set", "n_views=2", "--out-md", str(md), "--out-json", str(js)])
    out = capsys.readouterr().out
    assert "| ambient | 64x48 | main |" in out
    assert md.read_text() == out
    report = json.loads(js.read_text())
    assert report["runs"][0]["views"] == 2 and report["settings"]["overrides"] == {"n_views": 2}


@pytest.mark.parametrize("argv, message", [
    (["--sizes", "64by48"], "WIDTHxHEIGHT"),
    (["--presets", "nope"], "nope"),
    (["--samples", "0"], "samples"),
])
def test_cli_rejects_bad_arguments(argv, message, capsys):
    with pytest.raises(SystemExit) as error:
        main(["bench", *argv])
    assert message in str(error.value) + capsys.readouterr().err
