"""The occluder reach report (``benchmarks/occluder_reach.py``): which occluder centres lie over the
painting in a view, on hand-placed points, and what the command prints."""

import numpy as np
import pytest

from benchmarks import occluder_reach
from sidar_torch import geometry

SIZE = (96, 128)


def test_a_point_is_over_the_painting_only_below_the_camera_inside_the_image_and_the_painting():
    K, R, t = geometry.reference_camera(SIZE, 1.0)  # sees exactly the painting, 4/3 wide and 1 high
    over = lambda point: occluder_reach.centre_over_painting(K, R, t, SIZE, np.array(point, float))
    assert over([0.0, 0.0, 0.5]) and over([0.3, -0.2, 0.2])
    assert not over([0.0, 0.0, 1.5])  # behind the camera
    assert not over([0.9, 0.0, 0.1])  # outside the image and the painting
    wide = np.array([[K[0, 0] / 2, 0, K[0, 2]], [0, K[1, 1] / 2, K[1, 2]], [0, 0, 1]])  # twice the field of view
    assert not occluder_reach.centre_over_painting(wide, R, t, SIZE, np.array([0.9, 0.0, 0.1]))  # in the image, off the painting
    assert occluder_reach.centre_over_painting(wide, R, t, SIZE, np.array([0.5, 0.0, 0.1]))  # its ray meets x = 0.56


def test_the_command_prints_both_shares_and_names_a_wrong_override(capsys):
    occluder_reach.main(["--samples", "20", "--placements", "2"])
    out = capsys.readouterr().out.splitlines()
    assert out[1].startswith("occluder centres over the painting: view 0 0.")
    assert out[2].startswith("placements whose bounding sphere holds a camera of the sequence: 0.")
    with pytest.raises(SystemExit, match="n_occluder"):
        occluder_reach.main(["--set", "n_occluder=[1,1]", "--samples", "1"])
