"""The library's timing hook (``sidar_torch.timing``: ``timed`` steps, added to the collector a caller opens
with ``collect_timings``): it adds seconds only inside a collection, never mixes two collections, and
never changes a pixel."""

import threading

import numpy as np
import pytest
import torch

from sidar_torch.render import RenderSettings, shared_renderer
from sidar_torch.sample import render_sample
from sidar_torch.scene import sample_sequence
from sidar_torch.timing import collect_timings, stopwatch, timed

from conftest import small_config, textured_painting


def test_timed_adds_seconds_only_inside_a_collection():
    calls = []
    with timed("x", sync=lambda: calls.append(1)):
        pass
    assert calls == []  # no collector: not synced, nothing kept
    with collect_timings() as timings:
        for _ in range(2):
            with timed("x", sync=lambda: calls.append(1)):
                pass
        with pytest.raises(KeyError):
            with timed("y", sync=lambda: calls.append(1)):
                raise KeyError("boom")
    assert calls == [1, 1] and set(timings) == {"x", "y"} and timings["x"] > 0
    assert timings["y"] > 0  # failed block: timed, not synced
    with timed("z"):
        pass
    assert "z" not in timings  # closed: later steps go nowhere


def test_a_nested_collection_takes_its_own_block_and_the_outer_one_resumes():
    with collect_timings() as outer:
        with timed("a"):
            pass
        with collect_timings() as inner:
            with timed("b"):
                pass
        with timed("c"):
            pass
    assert set(outer) == {"a", "c"} and set(inner) == {"b"}


def test_collections_of_two_threads_do_not_mix():
    started, results = threading.Barrier(2), {}

    def work(name):
        with collect_timings() as timings:
            started.wait()  # both collectors open at once
            for _ in range(50):
                with timed(name):
                    pass
            started.wait()
        results[name] = timings

    threads = [threading.Thread(target=work, args=(name,)) for name in ("first", "second")]
    with collect_timings() as main:  # a thread does not inherit this one either
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
    assert set(results["first"]) == {"first"} and set(results["second"]) == {"second"}
    assert main == {}


def test_a_stopwatch_adds_to_the_dict_it_is_given():
    parts = {}
    for _ in range(2):
        with stopwatch(parts, "x"):
            pass
    assert set(parts) == {"x"} and parts["x"] > 0


@pytest.mark.gl  # renders
def test_timings_do_not_change_pixels():
    config = small_config()
    index = next(i for i in range(100)
                 if any(v.occluders for v in sample_sequence(config, np.random.default_rng([0, i])).views))
    sequence = sample_sequence(config, np.random.default_rng([0, index]))
    painting = textured_painting(config.image_size)
    renderer = shared_renderer(RenderSettings.from_config(config))
    plain = render_sample(renderer, sequence, painting, config, index)
    with collect_timings() as timings:
        measured = render_sample(renderer, sequence, painting, config, index)
    for key in ("images", "masks", "label", "homographies", "K", "R", "t"):
        assert torch.equal(plain[key], measured[key]), key
    assert set(timings) == {"upload", "graph", "shadow", "colour", "mask", "label", "readback",
                            "homographies", "tensors"}
    assert all(v > 0 for v in timings.values())
