"""A process that may fork renders its own samples in a render process (``sidar_torch.render.process``):
the same bytes as rendering in the process, Mesa's disk cache on there, the process itself free of GL,
so DataLoader workers forked after its samples render (and compile, and write the cache) without a
deadlock; a render process that dies, an exception raised there, a forked copy of one.

The suite renders in its own process (``conftest``: ``render_in_this_process``), so these run in fresh
interpreters, as a user's script does; every wait is bounded (``subprocess.run(timeout=)``, DataLoader
``timeout=``).
"""

import subprocess
import sys

import pytest

pytestmark = pytest.mark.gl  # renders

WAIT = 300
"""Seconds a script may take before the test fails (a deadlock fails instead of hanging the suite)."""

DEFAULT_PATH = """
import os, sys
import torch
from torch.utils.data import DataLoader
from sidar_torch import SidarDataset, load_config
from sidar_torch.render import RenderProcess, RenderSettings, shared_renderer
from sidar_torch.render import renderer as renderer_module
from sidar_torch.sample import render_arrays
from sidar_torch.scene import sample_sequence
from sidar_torch.timing import collect_timings

config = load_config("misaligned", image_size=(48, 64), n_views=2)
dataset = SidarDataset(config=config, seed=3)
assert isinstance(dataset.renderer(), RenderProcess), type(dataset.renderer())
remote = [dataset.sample(index) for index in (5, 6)]
with collect_timings() as seconds:  # the render process's steps reach this process's collector
    dataset.sample(7)
assert {"colour", "readback", "homographies"} <= seconds.keys(), seconds
assert not renderer_module._SHARED, "the main process opened a GL context"

# Workers forked now open their own contexts with the cache on and compile another preset's variants
# (cache writes): the render process's cache thread is not theirs, so nothing waits on it.
other = SidarDataset(config=load_config("shadows_only", image_size=(40, 56), n_views=2), seed=1)
batch = next(iter(DataLoader(other, batch_size=2, num_workers=2, timeout=240)))
assert batch["images"].shape == (2, 2, 3, 40, 56), batch["images"].shape
assert not renderer_module._SHARED, "the main process opened a GL context"

# The same samples rendered in this process (its context without the cache: it may fork).
local = shared_renderer(RenderSettings.from_config(config))
for index, sample in zip((5, 6), remote):
    rng = dataset.generator(index)
    sequence = sample_sequence(config, rng)
    painting = dataset.source.painting(index % len(dataset.source), config.image_size)
    here = render_arrays(local, sequence, painting, config, index, rng=rng).to_tensors(config.geometry_dtype)
    assert here.keys() == sample.keys(), (sorted(here), sorted(sample))
    for key, value in here.items():
        same = torch.equal(value, sample[key]) if torch.is_tensor(value) else value == sample[key]
        assert same, key
assert dataset.renderer().rasteriser() == local.rasteriser()
print("ok")
"""


def run(script: str, tmp_path, **env) -> subprocess.CompletedProcess:
    """Run ``script`` in a fresh interpreter, Mesa's disk cache on, in a cache folder of its own (cold)."""
    import os

    environment = {k: v for k, v in os.environ.items()
                   if k not in ("PYOPENGL_PLATFORM", "LP_NUM_THREADS", "MESA_SHADER_CACHE_DISABLE")}
    environment.update(MESA_SHADER_CACHE_DIR=str(tmp_path / "mesa"), **env)
    return subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=WAIT,
                          env=environment)


def test_a_process_that_may_fork_renders_in_a_render_process_the_same_bytes_and_forks_safely(tmp_path):
    result = run(DEFAULT_PATH, tmp_path)
    assert result.returncode == 0 and result.stdout.strip() == "ok", result.stderr[-3000:]
    assert any((tmp_path / "mesa").rglob("*")), "the render process wrote no shader cache"


FAILURES = """
import os, signal, time
import numpy as np
from sidar_torch import SidarDataset, load_config
from sidar_torch.render import RenderProcess

config = load_config("ambient", image_size=(24, 32), n_views=2)
dataset = SidarDataset(config=config, seed=0)
first = dataset.sample(0)
renderer = dataset.renderer()

# An exception raised there is raised here, with the render process's traceback as a note.
try:
    renderer.render(dataset.scene(0), np.zeros((5, 5, 3), np.uint8))
except ValueError as error:
    assert "painting" in str(error), error
    assert any(f"render process (pid {renderer.pid})" in note for note in error.__notes__), error.__notes__
else:
    raise AssertionError("no ValueError")

# A forked copy refuses calls, naming the owner.
child = os.fork()
if child == 0:
    try:
        renderer.render(dataset.scene(0), np.zeros((24, 32, 3), np.uint8))
    except RuntimeError as error:
        os._exit(0 if f"belongs to process {renderer.owner}" in str(error) else 3)
    os._exit(4)
assert os.waitpid(child, 0)[1] == 0

# Ctrl-C in a terminal reaches the render process too: it ignores it (its parent decides).
os.kill(renderer.pid, signal.SIGINT)
time.sleep(0.3)
assert renderer.usable and dataset.renderer().pid == renderer.pid
dataset.sample(1)

# A render process that dies: the call says so, the next sample starts a new one, the same bytes.
os.kill(renderer.pid, signal.SIGKILL)
try:
    renderer.render(dataset.scene(0), np.zeros((24, 32, 3), np.uint8))
except RuntimeError as error:
    assert f"render process (pid {renderer.pid}) died" in str(error), error
else:
    raise AssertionError("no RuntimeError")
again = dataset.sample(0)
assert dataset.renderer().pid != renderer.pid
assert all(np.array_equal(first[k], again[k]) for k in ("images", "masks", "label")), "different bytes"
print("ok")
"""


def test_render_process_failures_are_raised_where_it_is_called(tmp_path):
    result = run(FAILURES, tmp_path)
    assert result.returncode == 0 and result.stdout.strip() == "ok", result.stderr[-3000:]


POOL_WORKER = """
import multiprocessing
from sidar_torch import SidarDataset, load_config

def first_pixels(index):
    from sidar_torch.render import SceneRenderer
    dataset = SidarDataset(config=load_config("ambient", image_size=(24, 32), n_views=2), seed=0)
    assert isinstance(dataset.renderer(), SceneRenderer), type(dataset.renderer())  # it may have no children
    return dataset.sample(index)["images"].sum().item()

if __name__ == "__main__":
    with multiprocessing.get_context("fork").Pool(1) as pool:
        print("ok" if pool.map(first_pixels, [0]) else "empty")
"""


def test_a_daemonic_pool_worker_renders_in_itself(tmp_path):
    result = run(POOL_WORKER, tmp_path)
    assert result.returncode == 0 and result.stdout.strip() == "ok", result.stderr[-3000:]


INTERRUPTED = """
import os, signal, threading
import numpy as np
from sidar_torch import SidarDataset, load_config

dataset = SidarDataset(config=load_config("misaligned", image_size=(96, 128), n_views=3), seed=0)
first = dataset.sample(0)
renderer = dataset.renderer()
os.kill(renderer.pid, signal.SIGSTOP)  # the next call waits for as long as the render process is stopped
signal.signal(signal.SIGALRM, lambda *_: (_ for _ in ()).throw(KeyboardInterrupt))
signal.setitimer(signal.ITIMER_REAL, 0.5)  # Ctrl-C while it waits
try:
    dataset.sample(1)
except KeyboardInterrupt:
    pass
else:
    raise AssertionError("not interrupted")
assert not renderer.usable
# The next samples come from a new render process, each its own (no late reply of the interrupted call).
again = [dataset.sample(0), dataset.sample(2)]
assert dataset.renderer().pid != renderer.pid
assert np.array_equal(first["images"], again[0]["images"])
# Threads take turns on one render process: each gets its own sample.
out = {}
threads = [threading.Thread(target=lambda i=i: out.__setitem__(i, dataset.sample(i))) for i in (0, 2)]
for thread in threads:
    thread.start()
for thread in threads:
    thread.join(120)
assert np.array_equal(out[0]["images"], first["images"]) and np.array_equal(out[2]["images"], again[1]["images"])
print("ok")
"""


def test_an_interrupted_call_ends_the_render_process_and_threads_take_turns(tmp_path):
    result = run(INTERRUPTED, tmp_path)
    assert result.returncode == 0 and result.stdout.strip() == "ok", result.stderr[-3000:]


NOTICE = """
from sidar_torch import SidarDataset, load_config

dataset = SidarDataset(config=load_config("ambient", image_size=(24, 32), n_views=2), seed=0)
for index in range(3):
    dataset.sample(index)
"""


def test_a_cold_cache_says_once_that_it_compiles_and_a_warm_one_says_nothing(tmp_path):
    cold, warm = run(NOTICE, tmp_path), run(NOTICE, tmp_path)  # the same cache folder: empty, then filled
    assert cold.returncode == 0 and warm.returncode == 0, cold.stderr[-3000:] + warm.stderr[-3000:]
    assert cold.stderr.count("sidar_torch: compiling the renderer's shader variants") == 1, cold.stderr
    assert str(tmp_path / "mesa") in cold.stderr
    assert warm.stderr == "", warm.stderr
