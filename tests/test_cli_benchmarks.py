"""The benchmark commands: ``evaluate`` prints the tables and writes ``--json``, ``export --testset``
checks the digests and refuses what a set pins, ``export --layout paper`` writes the paper's files."""

import json

import numpy as np
import pytest

from conftest import TINY
from sidar_torch.cli import main
from test_evaluation import H_TRUE, export


def estimate(source, target):
    """A ``MODULE:FUNC`` estimator for the command line: the hand-made sets' true homography."""
    return H_TRUE


def test_evaluate_prints_the_tables_and_writes_json(tmp_path, capsys):
    folder = export(tmp_path / "set")
    main(["evaluate", "--testset", str(folder), "--estimator", "test_cli_benchmarks:estimate",
          "--json", str(tmp_path / "out.json")])
    out = capsys.readouterr().out
    assert "| **total** | 4 | 0.00 | 0.00 | 100 % | 100 % | 100 % | 0 |" in out and "| tilt_deg | [0, 20) |" in out
    result = json.loads((tmp_path / "out.json").read_text())
    assert result["estimator"] == "test_cli_benchmarks:estimate" and result["pairs"] == 4 and result["mace"] < 1e-9
    assert set(result["success"]) == {"1", "3", "10"} and set(result["by_category"]) == {"set"}


@pytest.mark.parametrize("argv, message", [
    (["evaluate", "--estimator", "nope"], "--estimator: expected one of ['ecc', "),
    (["evaluate", "--estimator", "sift", "--testset", "no-such-set"], "--testset 'no-such-set': expected one of"),
    (["evaluate", "--estimator", "sift", "--limit", "0"], "--limit 0: expected at least 1"),
    (["export", "--testset", "homography-v1", "--out", "x", "--set", "n_views=3"], "--set: --testset homography-v1 pins"),
    (["export", "--testset", "homography-v2", "--out", "x"], "testset: expected one of ['homography-v1'"),
    (["export", "--out", "x"], "--count: required (unless --testset names a test set)"),
    (["export", "--out", "x", "--count", "1", "--layout", "paper", "--ray"], "--layout paper: Ray's export writes"),
])
def test_wrong_benchmark_options_are_one_line_naming_them(argv, message, capsys):
    with pytest.raises(SystemExit) as exit_:
        main(argv)
    assert exit_.value.code == 2 and message in capsys.readouterr().err


@pytest.mark.gl
def test_export_in_the_paper_layout(tmp_path, capsys):
    main(["export", "--out", str(tmp_path), "--count", "1", "--layout", "paper", "--no-progress",
          "--set", f"image_size={list(TINY['image_size'])}", "--set", "n_views=3"])
    names = {p.name for p in (tmp_path / "000000").iterdir()}
    assert {"H_0_1.mat", "H_0_2.mat", "H_1_2.mat", "gt.png", "0-m.png", "homographies.npy"} <= names
    assert "H_1_0.mat" not in names
    assert np.loadtxt(tmp_path / "000000" / "H_1_2.mat").shape == (3, 3)


@pytest.mark.slow
@pytest.mark.gl
def test_evaluate_sift_on_the_first_20_pairs_of_homography_v1(tmp_path, capsys):
    pytest.importorskip("cv2")
    main(["evaluate", "--testset", "homography-v1", "--estimator", "sift", "--limit", "20", "--no-progress",
          "--cache", str(tmp_path / "cache"), "--json", str(tmp_path / "sift.json")])
    out = capsys.readouterr().out
    assert "homography-v1: 20 pairs, estimator sift" in out and "| **total** | 20 |" in out
    result = json.loads((tmp_path / "sift.json").read_text())
    assert result["pairs"] == 20 and list(result["by_category"]) == ["clean", "lights", "shadows", "occlusions", "all"]
    assert result["success"]["10"] > 0.5  # SIFT finds most of these (the recorded run: 20 of 20 within 3 px)
