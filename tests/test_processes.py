"""Processes: DataLoader start methods and worker counts, persistent workers, a worker that dies,
a clean exit, other runs and distributed ranks, all giving byte-identical samples.

Every wait is bounded (DataLoader ``timeout=``, ``subprocess.run(timeout=)``, a deadline on
joining ranks), so a deadlock fails the test instead of hanging the suite.
"""

import datetime
import functools
import json
import os
import re
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest
import torch
import torch.distributed as dist
from torch.utils.data import DataLoader

from sidar_torch import SidarDataset, load_config

from conftest import sample_digest, small_config

pytestmark = pytest.mark.gl  # renders

WAIT = 300
"""Seconds any one wait may take before the test fails."""

TESTS = Path(__file__).resolve().parent

TINY = load_config("ambient", image_size=(24, 32), n_views=2)
"""A cheap config for tests about who draws which index."""


def fresh_env(**extra):
    """This environment without the variables ``sidar_torch`` sets on import, as a new user's
    process starts (plus ``extra``)."""
    env = {k: v for k, v in os.environ.items()
           if k not in ("PYOPENGL_PLATFORM", "LP_NUM_THREADS", "MESA_SHADER_CACHE_DISABLE")}
    return {**env, **extra}


def run_script(path, text, **env):
    """Run ``text`` as the Python script ``path`` in a fresh interpreter; returns the finished process."""
    path.write_text(f"import sys\nsys.path.insert(0, {str(TESTS)!r})\n{text}")
    return subprocess.run([sys.executable, str(path)], capture_output=True, text=True, timeout=WAIT,
                          env=fresh_env(**env))


# --------------------------------------------------------------------------- start methods


@pytest.mark.filterwarnings("ignore:This DataLoader will create 3 worker processes")  # more than 2 cores
@pytest.mark.parametrize("context, num_workers", [("fork", 3), ("spawn", 2), ("forkserver", 1)])
def test_workers_yield_each_index_once_with_the_same_content(context, num_workers):
    # The parent renders first, with a simpler preset, so the workers must compile shader
    # variants the parent never built: that is what deadlocked forked children while Mesa's
    # disk-cache thread lived in the parent. The timeout turns a hang into a failure.
    SidarDataset(config=small_config("ambient", n_views=1), seed=0).sample(0)
    ds = SidarDataset(config=small_config(n_views=2, n_lights=(2, 3), n_occluders=(1, 2)), seed=4, length=7)
    loader = DataLoader(ds, batch_size=None, num_workers=num_workers, multiprocessing_context=context, timeout=WAIT)
    drawn = [(int(s["index"]), sample_digest(s)) for s in loader]
    assert sorted(i for i, _ in drawn) == list(range(7))
    assert dict(drawn) == {i: sample_digest(ds.sample(i)) for i in range(7)}


class _RendererOfEachSample(torch.utils.data.IterableDataset):
    """Samples ``0 .. length - 1`` of ``dataset`` (sharded over the workers), each with the ``id`` of
    the renderer that drew it and the programs that renderer had built before and after it."""

    def __init__(self, dataset, length):
        self.dataset, self.length = dataset, length

    def __iter__(self):
        from sidar_torch.render import RenderSettings, shared_renderer

        info = torch.utils.data.get_worker_info()
        renderer = shared_renderer(RenderSettings.from_config(self.dataset.config))
        for index in range(info.id, self.length, info.num_workers):
            before = renderer.program_count
            digest = sample_digest(self.dataset.sample(index))
            yield index, digest, id(renderer), before, renderer.program_count


def test_forked_workers_take_over_the_warm_renderer_of_their_parent_and_compile_nothing():
    from sidar_torch.render import RenderSettings, shared_renderer

    ds = SidarDataset(config=small_config(n_views=2, n_occluders=(2, 3)), seed=5)
    ds.warm_up()
    parent = shared_renderer(RenderSettings.from_config(ds.config))
    loader = DataLoader(_RendererOfEachSample(ds, 4), batch_size=None, num_workers=2, multiprocessing_context="fork",
                        timeout=WAIT)
    drawn = list(loader)
    assert sorted(index for index, *_ in drawn) == [0, 1, 2, 3]
    for index, digest, renderer, before, after in drawn:
        assert renderer == id(parent), "the worker made a renderer of its own"
        assert before == after == parent.program_count, f"sample {index} compiled in the worker"
        assert digest == sample_digest(ds.sample(index))


def _note_worker_start(path, worker_id):
    with open(path, "a") as log:
        log.write(f"{worker_id} {os.getpid()}\n")


def test_persistent_workers_serve_every_epoch_with_the_same_content(tmp_path):
    starts = tmp_path / "starts"
    ds = SidarDataset(config=small_config(n_views=2), seed=5, length=5)
    loader = DataLoader(ds, batch_size=None, num_workers=2, persistent_workers=True, timeout=WAIT,
                        worker_init_fn=functools.partial(_note_worker_start, starts))
    epochs = [{int(s["index"]): sample_digest(s) for s in loader} for _ in range(2)]
    assert len(starts.read_text().splitlines()) == 2  # the same two workers served both epochs
    assert epochs[0] == epochs[1] == {i: sample_digest(ds.sample(i)) for i in range(5)}


class IndexOnly(SidarDataset):
    """A SidarDataset whose samples are just their index: tests of who draws what, without rendering."""

    def sample(self, index):
        return {"index": index}


def indices_per_epoch(ds, batch_size, context, epochs=2):
    """The sorted indices that 2 persistent workers yield in each epoch, ``set_epoch`` called before each."""
    loader = DataLoader(ds, batch_size=batch_size, num_workers=2, persistent_workers=True, timeout=WAIT,
                        multiprocessing_context=context)
    drawn = []
    for epoch in range(epochs):
        ds.set_epoch(epoch)
        drawn.append(sorted(int(i) for batch in loader for i in batch["index"]))
    return drawn


@pytest.mark.parametrize("context", ["fork", "spawn"])
def test_set_epoch_reaches_persistent_workers_under_torchrun_ranks(monkeypatch, context):
    """Issue 20 item 3: persistent workers (which keep the dataset they started with) draw each
    epoch's fresh indices, on a single process and as rank 0 of 2 (torchrun's RANK/WORLD_SIZE)."""
    drawn = indices_per_epoch(IndexOnly(None, TINY, seed=0, length=64), 16, context, epochs=3)
    assert drawn == [list(range(64 * e, 64 * e + 64)) for e in range(3)]
    monkeypatch.setenv("RANK", "0")
    monkeypatch.setenv("WORLD_SIZE", "2")
    drawn = indices_per_epoch(IndexOnly(None, TINY, seed=0, length=16), 2, context)
    assert drawn == [[0, 1, 4, 5, 8, 9, 12, 13], [16, 17, 20, 21, 24, 25, 28, 29]]


# --------------------------------------------------------------------------- failure and exit


class DyingImages:
    """16 grey images; reading item ``die_at`` ends the reading process: ``"kill"`` by SIGKILL
    (as the kernel's out-of-memory killer does), ``"exit"`` by ``os._exit(3)`` (as a crashing
    extension might)."""

    def __init__(self, die_at, how):
        self.die_at, self.how = die_at, how

    def __len__(self):
        return 16

    def __getitem__(self, index):
        if index == self.die_at:
            if self.how == "kill":
                os.kill(os.getpid(), signal.SIGKILL)
            os._exit(3)
        return torch.full((3, 24, 32), index / 16)


@pytest.mark.parametrize("how", ["kill", "exit"])
def test_a_worker_that_dies_raises_in_the_loop_instead_of_hanging(how):
    ds = SidarDataset(source=DyingImages(die_at=3, how=how), config=TINY, length=16)
    loader = DataLoader(ds, batch_size=None, num_workers=2, timeout=WAIT)
    started = time.monotonic()
    # DataLoader's own message (its timeout would say "timed out" and fail the match); or, when the worker
    # dies while this process fetches the storage of a sample it sent (torch shares it through a socket to
    # the worker), that socket's reset.
    with pytest.raises((RuntimeError, ConnectionResetError)) as raised:
        for _ in loader:
            pass
    if isinstance(raised.value, RuntimeError):
        assert re.search(r"DataLoader worker \(pid", str(raised.value)), raised.value
    assert time.monotonic() - started < 60


RENDER_AND_EXIT = """
from torch.utils.data import DataLoader
from conftest import small_config
from sidar_torch import SidarDataset

if __name__ == "__main__":
    ds = SidarDataset(config=small_config(n_views=2), length=2)
    ds.sample(0)
    for _ in DataLoader(ds, batch_size=None, num_workers=1, multiprocessing_context={context!r}, timeout={wait}):
        pass
"""


@pytest.mark.parametrize("context", ["fork", "spawn"])
def test_a_process_that_rendered_exits_cleanly_and_silently(tmp_path, context):
    # The parent and its worker each render, then everything is released at exit: any GL or
    # pyrender complaint from a finalizer would land on stderr.
    done = run_script(tmp_path / "render_and_exit.py", RENDER_AND_EXIT.format(context=context, wait=WAIT))
    assert (done.returncode, done.stderr) == (0, "")


# --------------------------------------------------------------------------- other runs


DIGESTS = """
import json
from conftest import sample_digest, small_config
from sidar_torch import SidarDataset

ds = SidarDataset(config=small_config(n_views=3, n_occluders=(2, 3)), seed=9)
print(json.dumps({i: sample_digest(ds.sample(i)) for i in (0, 5)}))
"""


@pytest.mark.slow
def test_same_seed_and_index_give_the_same_bytes_in_another_run(tmp_path):
    # Another interpreter: a fresh renderer, another hash seed (so set and dict orders differ).
    done = run_script(tmp_path / "digests.py", DIGESTS, PYTHONHASHSEED="12345")
    assert done.returncode == 0, done.stderr
    other_run = {int(i): digest for i, digest in json.loads(done.stdout).items()}
    ds = SidarDataset(config=small_config(n_views=3, n_occluders=(2, 3)), seed=9)
    assert other_run == {i: sample_digest(ds.sample(i)) for i in (5, 0)}


# --------------------------------------------------------------------------- distributed ranks


def _free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _rank_main(rank, init_method, out, length):
    """One of 2 gloo ranks: draw ``SidarDataset(TINY, length)`` through 2 workers; rank 0 writes
    every rank's ``[(index, digest), ...]`` to ``out``."""
    dist.init_process_group("gloo", init_method=init_method, rank=rank, world_size=2,
                            timeout=datetime.timedelta(seconds=WAIT))
    try:
        # Rank 0's workers are forked and inherit the initialised process group; rank 1's are
        # spawned and know their rank only from the pickled dataset.
        context = ("fork", "spawn")[rank]
        ds = SidarDataset(config=TINY, seed=11, length=length)
        loader = DataLoader(ds, batch_size=None, num_workers=2, multiprocessing_context=context, timeout=WAIT)
        drawn = [(int(s["index"]), sample_digest(s)) for s in loader]
        gathered = [None, None]
        dist.all_gather_object(gathered, drawn)
        if rank == 0:
            Path(out).write_text(json.dumps(gathered))
    finally:
        dist.destroy_process_group()


@pytest.mark.slow
def test_ranks_and_workers_draw_disjoint_shards_covering_length_once(tmp_path):
    length = 10  # not a multiple of the 4 shards: shards differ by one sample
    out = tmp_path / "gathered.json"
    ranks = torch.multiprocessing.start_processes(
        _rank_main, args=(f"tcp://127.0.0.1:{_free_port()}", str(out), length), nprocs=2, join=False,
        start_method="spawn")
    deadline = time.monotonic() + WAIT
    try:
        while not ranks.join(timeout=2):  # raises if a rank raised or died
            assert time.monotonic() < deadline, "the ranks did not finish"
    finally:
        for process in ranks.processes:
            if process.is_alive():
                process.kill()
    gathered = json.loads(out.read_text())
    assert sorted(i for drawn in gathered for i, _ in drawn) == list(range(length))
    for rank, drawn in enumerate(gathered):  # rank r holds shards 2r and 2r + 1 of 4
        assert {i % 4 for i, _ in drawn} == {2 * rank, 2 * rank + 1}
    ds = SidarDataset(config=TINY, seed=11)
    assert {i: digest for drawn in gathered for i, digest in drawn} == {i: sample_digest(ds.sample(i))
                                                                         for i in range(length)}


PRELOAD = """
import sys
from sidar_torch import SidarDataset
assert "pyrender" not in sys.modules
SidarDataset()
from sidar_torch.render import renderer
assert "pyrender" in sys.modules and "OpenGL.GL" in sys.modules
assert not renderer._SHARED, renderer._SHARED
print("preloaded without a context")
"""


def test_the_dataset_imports_the_renderer_for_its_workers_and_creates_no_context():
    result = subprocess.run([sys.executable, "-c", PRELOAD], capture_output=True, text=True, timeout=120)
    assert result.stdout.strip() == "preloaded without a context", result.stderr[-2000:]


DISK_CACHE = """
import os, sys
os.environ.pop("MESA_SHADER_CACHE_DISABLE", None)
from sidar_torch.render import context
if sys.argv[1] == "pool-worker":
    context.forks_nothing()
context._disable_disk_cache_unless_worker()
print(os.environ.get("MESA_SHADER_CACHE_DISABLE"))
"""


@pytest.mark.parametrize("role, expected", [("main", "true"), ("pool-worker", "None")])
def test_only_processes_that_may_fork_turn_mesas_disk_cache_off(role, expected):
    result = subprocess.run([sys.executable, "-c", DISK_CACHE, role], capture_output=True, text=True, timeout=120)
    assert result.stdout.strip() == expected, result.stderr[-2000:]
