"""Rendering on a Ray cluster (``sidar_torch.io.cluster``): on a local cluster of 2 CPUs, the rows of
``ray_dataset`` are the samples rendered here, and ``ray_export`` writes the files of
``export_dataset`` byte for byte, resuming and surviving a killed worker. Without Ray, each entry
point names the extra to install (those tests need no Ray); the others skip when Ray is absent."""

import contextlib
import os
import signal
import subprocess
import sys
import textwrap
import threading
import time
import tomllib
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import torch

from conftest import same_tensor, small_config
from export_digests import tree_digests
from sidar_torch import ExportedDataset, SidarDataset, export_dataset
from sidar_torch.cli import main
from sidar_torch.io import cluster as cluster_module
from sidar_torch.io.cluster import RAY_REQUIREMENT, ray_dataset, ray_export, torch_batches
from sidar_torch.io import export as export_module
from sidar_torch.io.export import ExportPlan
from sidar_torch.io.folders import FolderLayout
from sidar_torch.sample import SampleArrays

HINT = r'pip install "ray\[data\]>=2.9"'


@pytest.fixture(scope="module")
def cluster():
    """A local Ray cluster of 2 CPUs for the module, shut down after it."""
    ray = pytest.importorskip("ray")
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield ray
    ray.shutdown()


@pytest.fixture(scope="module")
def dataset():
    """Tiny sequences (24 x 32, 3 views, every optional output on: every column of a row is exercised)."""
    return SidarDataset(config=small_config(image_size=(24, 32), shadow_map_size=256, opacity_output=True,
                                            shadow_mask_output=True, shadow_free_output=True, depth_output=True,
                                            flow_output=True), seed=5)


# --------------------------------------------------------------------------- without Ray


def test_without_ray_each_entry_point_names_the_extra(monkeypatch, tmp_path, capsys):
    monkeypatch.setitem(sys.modules, "ray", None)  # `import ray` raises ImportError, as when it is not installed
    dataset = SidarDataset(config=small_config())
    with pytest.raises(ImportError, match=HINT):
        ray_dataset(dataset, 2)
    with pytest.raises(ImportError, match=HINT):
        ray_export(dataset, tmp_path / "out", 2)
    assert not (tmp_path / "out").exists()
    with pytest.raises(SystemExit) as exit_:
        main(["export", "--out", str(tmp_path / "cli"), "--count", "1", "--ray"])
    assert exit_.value.code == 2
    assert capsys.readouterr().err.strip().splitlines() == [
        'sidar_torch export: Ray is not installed: pip install "ray[data]>=2.9"']


def test_the_install_hint_is_the_ray_extras_requirement():
    """Issue 20 item 6: ``pip install "sidar_torch[ray]"`` does not work for a package installed
    from a clone; the hint names Ray's own requirement, the one the extra installs."""
    pyproject = tomllib.loads((Path(__file__).parents[1] / "pyproject.toml").read_text())
    assert pyproject["project"]["optional-dependencies"]["ray"] == [RAY_REQUIREMENT]


class FakeRay:
    """Stands for Ray in ``cluster._run_tasks`` on a virtual clock: ``cpus`` workers, each ready
    after ``startup`` seconds, run the tasks in submission order; a task of ``n`` sequences takes
    ``n * per_sequence`` seconds and reports them as its busy time."""

    def __init__(self, cpus, startup, per_sequence):
        self.cpus, self.per_sequence, self.clock = cpus, per_sequence, 0.0
        self.free = [startup] * cpus  # when each worker is next free

    def cluster_resources(self):
        return {"CPU": self.cpus}

    def put(self, value):
        return value

    def remote(self, function):
        return SimpleNamespace(options=lambda **_: SimpleNamespace(remote=self._submit))

    def _submit(self, dataset, out, layout, units, driver):
        indices = [index for unit in units for index in unit.indices]
        worker = min(range(self.cpus), key=self.free.__getitem__)
        self.free[worker] += len(indices) * self.per_sequence
        return SimpleNamespace(finish=self.free[worker], result=(len(indices), len(indices) * self.per_sequence))

    def wait(self, pending, num_returns):
        first = min(pending, key=lambda ref: ref.finish)
        self.clock = first.finish
        return [first], [ref for ref in pending if ref is not first]

    def get(self, ref):
        return ref.result


class Recorder:
    """A non-terminal stderr that records ``(virtual time, line)``."""

    def __init__(self, ray):
        self.ray, self.lines = ray, []

    def write(self, text):
        self.lines.append((self.ray.clock, text))

    def flush(self):
        pass

    def isatty(self):
        return False


@pytest.mark.parametrize("cpus", [2, 16])
def test_the_ray_progress_line_estimates_the_time_left(monkeypatch, cpus):
    """Issue 20 item 6: the ``--ray`` ETA said 1713 s when 22 s were left (the line was drawn after
    the first of a finished task's 16 sequences, as if one sequence had taken the whole start-up)."""
    ray = FakeRay(cpus, startup=10.0, per_sequence=1.0)
    stderr = Recorder(ray)
    monkeypatch.setattr(export_module, "time", SimpleNamespace(perf_counter=lambda: ray.clock))
    monkeypatch.setattr(sys, "stderr", stderr)
    plan = ExportPlan(Path("out"), FolderLayout(), set(), list(range(400)))
    cluster_module._run_tasks(ray, None, plan, progress=True)
    end = ray.clock
    estimates = [(at, float(line.split(" s left")[0].rsplit(", ", 1)[1])) for at, line in stderr.lines
                 if "s left" in line]
    assert len(estimates) >= 3 and stderr.lines[-1][1].startswith("export: 400/400 sequences")
    assert not stderr.lines[-2][1].startswith("export: 400/400")  # the last line is drawn once
    for at, left in estimates:
        assert abs(left - (end - at)) <= 0.25 * (end - at) + 5, (at, left, end - at)


@pytest.mark.parametrize("argv, named", [(["--ray-address", "auto"], "--ray-address 'auto': add --ray"),
                                         (["--ray", "--workers", "2"], "--workers 2")])
def test_cli_ray_options_that_do_not_fit_are_a_usage_error(tmp_path, capsys, argv, named):
    with pytest.raises(SystemExit) as exit_:
        main(["export", "--out", str(tmp_path / "out"), "--count", "1", *argv])
    assert exit_.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and named in err[0], err
    assert not (tmp_path / "out").exists()


# --------------------------------------------------------------------------- on a local cluster


def test_wrong_arguments_are_named(cluster, dataset, tmp_path):
    for call, kind, named in [
        (lambda: ray_dataset("misaligned", 2), TypeError, "dataset: expected a SidarDataset"),
        (lambda: ray_dataset(dataset, 0), ValueError, "count"),
        (lambda: ray_dataset(dataset, 2, start=-1), ValueError, "start"),
        (lambda: ray_dataset(dataset, 2, actors=0), ValueError, "actors"),
        (lambda: ray_dataset(dataset, 2, batch_size=0), ValueError, "batch_size"),
        (lambda: ray_dataset(dataset, 2, address="auto"), ValueError, "address: Ray is already initialised"),
        (lambda: ray_export(dataset, tmp_path / "out", 2, address=7), TypeError, "address"),
        (lambda: ray_export(dataset, tmp_path / "out", 2, shard_size=0), ValueError, "shard_size"),
    ]:
        with pytest.raises(kind, match=named):
            call()


@pytest.mark.slow
@pytest.mark.gl
def test_rows_and_torch_batches_are_the_samples_rendered_here(cluster, dataset):
    rows = ray_dataset(dataset, 3, start=4, actors=2).materialize()  # rendered once, read twice
    by_index = {int(row["index"]): SampleArrays(**row) for row in rows.take_all()}
    assert sorted(by_index) == [4, 5, 6]
    for index, got in by_index.items():
        want = dataset.sample_arrays(index)
        for name in ("images", "masks", "opacities", "shadow_masks", "shadow_free", "label", "homographies", "K", "R",
                     "t"):
            a, b = getattr(got, name), getattr(want, name)
            assert a.dtype == b.dtype and np.array_equal(a, b, equal_nan=a.dtype.kind == "f"), (index, name)
        assert got.homography_error == want.homography_error
    seen = []
    for batch in torch_batches(rows, batch_size=2):
        for b, index in enumerate(batch["index"].tolist()):
            want = dataset.sample(index)
            for key, value in want.items():
                expected = torch.as_tensor(value, dtype=batch[key].dtype)
                assert same_tensor(batch[key][b], expected), (index, key)
            seen.append(index)
    assert sorted(seen) == [4, 5, 6]


@pytest.mark.gl
@pytest.mark.parametrize("shard_size", [None, 2])
def test_ray_export_is_the_local_export_byte_for_byte(cluster, dataset, tmp_path, shard_size):
    local = export_dataset(dataset, tmp_path / "local", count=5, start=1, shard_size=shard_size, progress=False)
    on_ray = ray_export(dataset, tmp_path / "ray", count=5, start=1, shard_size=shard_size, progress=False)
    assert on_ray.written == local.written == (1, 2, 3, 4, 5) and on_ray.present == 0
    assert tree_digests(tmp_path / "ray") == tree_digests(tmp_path / "local")
    assert ExportedDataset(tmp_path / "ray").indices == [1, 2, 3, 4, 5]


@pytest.mark.gl
def test_a_rerun_writes_only_what_is_missing(cluster, dataset, tmp_path):
    out = tmp_path / "ray"
    ray_export(dataset, out, count=4, progress=False)
    # What a run killed part-way leaves: sequence 2 never written, sequence 3 half-written.
    for name in ("000002", "000003"):
        for file in (out / name).iterdir():
            file.unlink()
        (out / name).rmdir()
    (out / ".tmp-sidar-000003").mkdir()
    (out / ".tmp-sidar-000003" / "0.png").write_bytes(b"half a png")
    summary = ray_export(dataset, out, count=6, progress=False)
    assert summary.written == (2, 3, 4, 5) and summary.present == 2
    export_dataset(dataset, tmp_path / "local", count=6, progress=False)
    assert tree_digests(out) == tree_digests(tmp_path / "local")
    again = ray_export(dataset, out, count=6, progress=False)  # everything there: nothing rendered
    assert again.written == () and again.present == 6


def _task_workers(name: str) -> list[int]:
    """Pids of the Ray worker processes now running task ``name`` (Ray titles them ``ray::<name>``)."""
    pids = []
    for cmdline in Path("/proc").glob("[0-9]*/cmdline"):
        try:
            if cmdline.read_bytes().startswith(f"ray::{name}".encode()):
                pids.append(int(cmdline.parent.name))
        except OSError:
            continue
    return pids


@pytest.mark.gl
def test_a_worker_killed_mid_task_is_retried_and_the_export_is_unchanged(cluster, dataset, tmp_path):
    out = tmp_path / "ray"
    result = {}
    run = threading.Thread(target=lambda: result.update(
        summary=ray_export(dataset, out, count=6, shard_size=3, progress=False)))
    run.start()
    killed = None
    while run.is_alive() and killed is None:
        workers = _task_workers("_write")
        if workers:
            killed = workers[0]
            os.kill(killed, signal.SIGKILL)
        time.sleep(0.005)
    run.join()
    assert killed is not None, "no export task was seen running"
    assert result["summary"].written == (0, 1, 2, 3, 4, 5)
    export_dataset(dataset, tmp_path / "local", count=6, shard_size=3, progress=False)
    assert tree_digests(out) == tree_digests(tmp_path / "local")


@pytest.mark.gl
def test_cli_export_with_ray_joins_the_running_cluster(cluster, tmp_path, capsys):
    out = tmp_path / "out"
    main(["export", "--out", str(out), "--count", "2", "--ray", "--no-progress",
          "--set", "image_size=[24,32]", "--set", "n_views=2", "--set", "shadow_map_size=256"])
    assert "wrote 2 sequences" in capsys.readouterr().out
    assert ExportedDataset(out).indices == [0, 1]


DRIVER = textwrap.dedent("""
    import sys
    import ray
    from sidar_torch import SidarDataset, load_config
    from sidar_torch.io.cluster import ray_export
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    dataset = SidarDataset(config=load_config("misaligned", image_size=(24, 32), n_views=2, shadow_map_size=256))
    ray_export(dataset, sys.argv[1], count=400, progress=False)
""")


@pytest.mark.gl
@pytest.mark.slow  # starts its own Ray cluster: about 20 s
def test_tasks_stop_writing_when_the_driver_dies(tmp_path):
    """Issue 25 item 6: Ray's workers kept writing into the export 1-5 s after a ``kill -9`` of a
    driver that had started its own cluster (the export's lock died with the driver, so a rerun
    could already be writing there); now they stop within ``orphans.POLL_S`` (a quarter of a second)."""
    pytest.importorskip("ray")
    out = tmp_path / "out"
    driver = subprocess.Popen([sys.executable, "-c", DRIVER, str(out)], start_new_session=True,
                              stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 120
        while not (out.is_dir() and any(p.name.isdigit() for p in out.iterdir())):
            assert driver.poll() is None, driver.stderr.read().decode()[-2000:]
            assert time.monotonic() < deadline, "the driver wrote no sequence in 120 s"
            time.sleep(0.02)
        os.kill(driver.pid, signal.SIGKILL)
        driver.wait()
        time.sleep(1.0)  # the watch polls every 0.25 s; the rest is room for a loaded machine
        written = sorted(p.name for p in out.iterdir())
        time.sleep(4)  # Ray itself ends a dead driver's tasks 2-5 s after its death
        assert sorted(p.name for p in out.iterdir()) == written, "tasks kept writing after the driver died"
    finally:
        with contextlib.suppress(ProcessLookupError):  # the cluster it started (Ray's agents linger a minute)
            os.killpg(driver.pid, signal.SIGKILL)
        driver.wait()
        driver.stderr.close()


@pytest.mark.slow
@pytest.mark.gl
def test_ray_rows_carry_the_lens_and_its_maps(cluster):
    lensed = SidarDataset(config=small_config(image_size=(24, 32), shadow_map_size=256, lens_model="division",
                                              distortion_map_output=True), seed=5)
    rows = ray_dataset(lensed, 2, actors=1).take_all()
    assert sorted(int(row["index"]) for row in rows) == [0, 1]
    for row in rows:
        got = SampleArrays(**row)
        want = lensed.sample_arrays(got.index)
        for name in ("images", "masks", "lens", "distortion_maps"):
            a, b = getattr(got, name), getattr(want, name)
            assert a.dtype == b.dtype and np.array_equal(a, b), name
