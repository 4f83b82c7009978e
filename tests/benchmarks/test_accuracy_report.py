"""The accuracy report (``benchmarks/accuracy_report.py``) on tiny settings: it runs, meets its
targets, and its overrides reach every configuration it loads."""

import pytest

from benchmarks import accuracy_report
from benchmarks.accuracy_report import AccuracySettings, format_report, run_report
from sidar_torch import load_config

pytestmark = pytest.mark.gl  # renders


def test_accuracy_report_runs_and_meets_its_targets():
    settings = AccuracySettings(sizes=((131, 257),), samples=1, n_views=4, scenes=50)
    report = run_report(settings, log=lambda line: None)
    row = report["alignment"][0]
    assert row["pairs"] >= 3 and row["max_px"] <= 0.2
    assert report["homography"]["float64_px"] <= 1e-6
    assert report["label"][0]["min_psnr_db"] >= 45
    assert "131x257" in format_report(report) and "float64" in format_report(report)


def test_accuracy_overrides_reach_every_configuration_the_report_loads(monkeypatch):
    loaded = []

    def recording_load_config(preset, **fields):
        loaded.append((preset, fields))
        return load_config(preset, **fields)

    monkeypatch.setattr(accuracy_report, "load_config", recording_load_config)
    settings = AccuracySettings(sizes=((131, 257),), samples=1, n_views=2, scenes=2,
                                overrides={"fov_deg": (30, 31)})
    run_report(settings, log=lambda line: None)
    assert {preset for preset, _ in loaded} == {"ambient", "misaligned"}
    assert all(fields.get("fov_deg") == (30, 31) for _, fields in loaded)


def test_accuracy_command_rejects_bad_overrides_before_measuring():
    with pytest.raises(SystemExit, match="n_veiws"):
        accuracy_report.main(["--quick", "--set", "n_veiws=2"])
    with pytest.raises(SystemExit, match="n_views"):
        accuracy_report.main(["--quick", "--set", "n_views=2"])
