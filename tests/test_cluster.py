"""Rendering on a Ray cluster (``sidar_torch.cluster``): on a local cluster of 2 CPUs, the rows of
``ray_dataset`` are the samples rendered here, and ``ray_export`` writes the files of
``export_dataset`` byte for byte, resuming and surviving a killed worker. Without Ray, each entry
point names the extra to install (those tests need no Ray); the others skip when Ray is absent."""

import os
import signal
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
import torch

from conftest import small_config
from export_digests import tree_digests
from sidar_torch import ExportedDataset, SidarDataset, export_dataset
from sidar_torch.cli import main
from sidar_torch.cluster import ray_dataset, ray_export, torch_batches
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
    """Tiny sequences (24 x 32, 3 views, opacities on: every column of a row is exercised)."""
    return SidarDataset(config=small_config(image_size=(24, 32), shadow_map_size=256, opacity_output=True), seed=5)


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


@pytest.mark.gl
def test_rows_and_torch_batches_are_the_samples_rendered_here(cluster, dataset):
    rows = ray_dataset(dataset, 3, start=4, actors=2).materialize()  # rendered once, read twice
    by_index = {int(row["index"]): SampleArrays(**row) for row in rows.take_all()}
    assert sorted(by_index) == [4, 5, 6]
    for index, got in by_index.items():
        want = dataset.sample_arrays(index)
        for name in ("images", "masks", "opacities", "label", "homographies", "K", "R", "t"):
            a, b = getattr(got, name), getattr(want, name)
            assert a.dtype == b.dtype and np.array_equal(a, b), (index, name)
        assert got.homography_error == want.homography_error
    seen = []
    for batch in torch_batches(rows, batch_size=2):
        for b, index in enumerate(batch["index"].tolist()):
            want = dataset.sample(index)
            for key, value in want.items():
                expected = torch.as_tensor(value, dtype=batch[key].dtype)
                assert torch.equal(batch[key][b], expected), (index, key)
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
