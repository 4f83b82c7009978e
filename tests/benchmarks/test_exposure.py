"""The exposure comparison's command (``python -m benchmarks.exposure``): it needs the paper's
contact sheets named, never a default path of one machine, and says so when they are missing; and
its per-view statistics."""

import numpy as np
import pytest

from benchmarks import exposure
from benchmarks.exposure import MIN_CLIPPED, view_exposure


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


def test_clipped_pixels_still_coloured_are_counted_among_the_clipped_painting_pixels():
    view = np.full((1, 20, 30, 3), 90, np.uint8)
    view[0, :10, :10] = (255, 120, 60)  # clipped in red only: still coloured
    view[0, 10:, :10] = (255, 255, 255)  # clipped to white
    view[0, :, 10:15] = (255, 210, 254)  # clipped, every channel >= 200: not coloured
    masks = np.zeros((1, 20, 30), bool)
    masks[0, :5] = True  # masked pixels do not count: 50 coloured, 100 white, 75 pale
    assert view_exposure(view, masks).clipped_coloured[0] == pytest.approx(50 / 225)
    few = np.full((1, 20, 30, 3), 90, np.uint8)
    few[0].reshape(-1, 3)[: MIN_CLIPPED - 1] = (255, 0, 0)
    assert np.isnan(view_exposure(few, np.zeros((1, 20, 30), bool)).clipped_coloured[0])
