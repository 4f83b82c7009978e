"""The exposure comparison's command (``python -m benchmarks.exposure``): it needs the paper's
contact sheets named, never a default path of one machine, and says so when they are missing."""

import pytest

from benchmarks import exposure


def test_anchors_are_required(capsys):
    with pytest.raises(SystemExit):
        exposure.main([])
    assert "--anchors" in capsys.readouterr().err


def test_a_glob_matching_nothing_is_named(tmp_path):
    with pytest.raises(SystemExit, match="no contact sheet found") as error:
        exposure.main(["--anchors", str(tmp_path / "*.png")])
    assert str(tmp_path) in str(error.value)


def test_a_sheet_of_the_wrong_size_is_named(tmp_path):
    from PIL import Image

    Image.new("RGB", (100, 50)).save(tmp_path / "sheet.png")
    with pytest.raises(SystemExit, match="expected a 784 x 1474 contact sheet, got 100 x 50"):
        exposure.main(["--anchors", str(tmp_path / "*.png")])
