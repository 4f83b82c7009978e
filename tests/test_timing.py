"""The library's timing hook (``sidar_torch.timing.timed``, the ``timings`` argument of the
renderer and ``render_sample``): it adds seconds only when asked and never changes a pixel."""

import numpy as np
import pytest
import torch

from sidar_torch.sample import render_sample
from sidar_torch.scene import sample_sequence
from sidar_torch.timing import timed

from conftest import small_config, textured_painting

pytestmark = pytest.mark.gl  # renders


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
