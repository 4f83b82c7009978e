"""``benchmarks/paper_replay.py``: the paper generator's draws replayed, its scenes as ours."""

import math

import numpy as np
import pytest

from sidar_torch import geometry, load_config

from benchmarks import paper_replay
from sidar_torch.scene.description import FALLOFFS
from benchmarks.realism import paper_to_kornia

SIZE = (384, 512)

SEQ01_H_0_1 = np.array([
    [7.832742037176135819e-01, -3.252988134521676566e-01, 1.573275670242322803e+02],
    [-1.789080627027761772e-01, 7.013422965694373623e-01, 1.326290971724130543e+02],
    [-6.760033134463531816e-04, -1.079377180363987054e-03, 1.534642220587758121e+00]])
"""``H_0_1.mat`` of the paper generator's run seeded with ``np.random.seed(1)`` (its sequence 1,
512 x 384): view 0's pixels to view 1's, in its own pixel convention, written by its ``homography.py``."""


def test_replayed_draws_give_the_generators_own_cameras():
    cameras, views = paper_replay.paper_draws(1)
    assert len(cameras) == 5 and len(views) == 6
    assert np.allclose(cameras[0]["position"], [1.852195, -2.9554775, 6.75623487])
    assert math.isclose(cameras[0]["lens"], 25.057012652676033)
    assert [len(v["lights"]) for v in views] == [4, 2, 4, 2, 3, 4]  # 2-4 lights, 0-3 objects per view
    assert [len(v["objects"]) for v in views] == [1, 3, 3, 1, 3, 0]
    sequence = paper_replay.paper_sequence(cameras, views, SIZE, load_config("paper_misaligned"),
                                           np.random.default_rng(0))
    K, R, t = (np.stack([getattr(v.camera, name) for v in sequence.views]) for name in "KRt")
    ours = geometry.plane_induced_homographies(K, R, t)[0, 1]
    theirs = paper_to_kornia(SEQ01_H_0_1, SIZE)
    corners = np.array([[0, 0, 1], [511, 0, 1], [511, 383, 1], [0, 383, 1.0]]).T
    a, b = ours @ corners, theirs @ corners
    assert np.abs(a[:2] / a[2] - b[:2] / b[2]).max() < 0.01  # pixels: the same camera, aim and lens


def test_replayed_lights_are_the_generators_powers_cones_and_spreads():
    light = dict(position=np.array([0.0, 0.0, 14.0]), hsv=(0.0, 0.0), energy=4 * np.pi * 49, type="SPOT",
                 size=math.radians(60), blend=0.0)
    spot = paper_replay._our_light(light, SIZE)
    assert spot.intensity == pytest.approx(1.0)  # P / (4 pi 7^2): 1 at one painting unit
    assert spot.outer_cone == pytest.approx(math.radians(30)) and spot.inner_cone == pytest.approx(spot.outer_cone)
    point = paper_replay._our_light(dict(light, type="POINT"), SIZE)
    assert point.intensity == pytest.approx(1.0) and point.inner_cone > math.atan(math.hypot(2 / 3, 0.5) / 2)
    area = paper_replay._our_light(dict(light, type="AREA", energy=np.pi * 49, spread=math.radians(40)), SIZE)
    assert area.outer_cone == pytest.approx(math.radians(20))
    a = math.radians(20)
    assert area.intensity == pytest.approx(math.tan(a) / (math.tan(a) - a))  # spread_beam's centre: Cycles' peak
    assert area.smooth_falloff == FALLOFFS["area_spread"] and spot.smooth_falloff == FALLOFFS["spot_blend"]


def test_blender_aim_looks_at_the_origin_from_above():
    position = np.array([0.3, -0.4, 0.8])
    R = paper_replay.blender_aim(position)
    assert np.allclose(R @ R.T, np.eye(3)) and np.isclose(np.linalg.det(R), 1.0)
    assert np.allclose(R @ -position / np.linalg.norm(position), [0, 0, 1])  # the origin straight ahead
    assert np.allclose(paper_replay.blender_aim(np.array([0, 0, 2.0])), np.diag([1.0, -1.0, -1.0]))


def test_command_line_refuses_a_negative_population(tmp_path):
    with pytest.raises(SystemExit):
        paper_replay.main(["--anchors", str(tmp_path), "--population", "-1"])
