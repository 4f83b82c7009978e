"""Export and its reader: byte-identical round trips, both layouts, resuming after a crash or a kill,
refusing to mix settings, the command line."""

import os
import signal
import subprocess
import sys
import tarfile
import time
from pathlib import Path

import numpy as np
import pytest
import scipy.io
import torch
from PIL import Image

from sidar_torch import ExportedDataset, SidarDataset, export_dataset, load_config
from sidar_torch import cli
from sidar_torch import export as export_module
from sidar_torch.dataset import sequence_homographies

TINY = {"image_size": (24, 32), "n_views": 2, "shadow_map_size": 256}
SEQUENCE_FILES = {"0.png", "1.png", "0-m.png", "1-m.png", "gt.png", "H_0_1.mat", "H_1_0.mat", "cameras.json"}


def tiny_dataset(seed=0, **overrides):
    return SidarDataset(config=load_config("misaligned", **{**TINY, **overrides}), seed=seed)


def assert_same_sample(read, rendered):
    assert set(read) == set(rendered)
    for key, value in rendered.items():
        if isinstance(value, torch.Tensor):
            assert read[key].dtype == value.dtype and read[key].shape == value.shape, key
            assert torch.equal(read[key], value), key
        else:
            assert type(read[key]) is type(value) and read[key] == value, key


def tree(path):
    """``{relative path: bytes}`` of every file under ``path`` but the lock file."""
    return {str(p.relative_to(path)): p.read_bytes() for p in sorted(Path(path).rglob("*"))
            if p.is_file() and p.name != export_module.LOCK}


def test_folder_round_trip_is_byte_identical(tmp_path):
    ds = tiny_dataset(seed=5, n_views=3)
    summary = export_dataset(ds, tmp_path, count=3, start=2, progress=False)
    assert summary.written == (2, 3, 4) and summary.present == 0
    read = ExportedDataset(tmp_path)
    assert len(read) == 3 and read.indices == [2, 3, 4] and read.seed == 5 and read.layout == "folders"
    for k, index in enumerate(read.indices):
        assert_same_sample(read[k], ds.sample(index))
    assert_same_sample(read[-1], read[2])

    folder = tmp_path / "000003"
    names = {p.name for p in folder.iterdir()}
    assert names == {"0.png", "1.png", "2.png", "0-m.png", "1-m.png", "2-m.png", "gt.png", "cameras.json"} | {
        f"H_{i}_{j}.mat" for i in range(3) for j in range(3) if i != j}
    mask = np.array(Image.open(folder / "1-m.png"))
    assert mask.dtype == np.uint8 and set(np.unique(mask)) <= {0, 255}
    assert np.array_equal(mask == 255, ds.sample(3)["masks"][1, 0].numpy() == 1)
    H = scipy.io.loadmat(folder / "H_2_0.mat")["H"]
    assert H.dtype == np.float64 and H.shape == (3, 3)
    assert np.array_equal(H, sequence_homographies(ds.scene(3))[0][2, 0].numpy())  # float64, not the float32 copy
    assert load_config(tmp_path / "config.yaml") == ds.config


def test_shards_round_trip_resume_and_match_an_uninterrupted_export(tmp_path):
    ds = tiny_dataset(seed=1)
    export_dataset(ds, tmp_path / "a", count=3, start=1, shards=2, progress=False)
    with tarfile.open(tmp_path / "a" / "shard-00001.tar") as tar:
        names = tar.getnames()
    assert names[:2] == ["000002.0.png", "000002.0-m.png"] and "000003.homographies.npy" in names
    read = ExportedDataset(tmp_path / "a")
    assert read.layout == "shards" and read.indices == [1, 2, 3]
    for k, index in enumerate(read.indices):
        assert_same_sample(read[k], ds.sample(index))

    # More sequences into the same folder: only 0 and 4 are rendered, shard 0 keeps sequence 1's bytes.
    summary = export_dataset(ds, tmp_path / "a", count=5, shards=2, progress=False)
    assert summary.written == (0, 4) and summary.present == 3
    export_dataset(ds, tmp_path / "b", count=5, shards=2, workers=2, progress=False)
    assert tree(tmp_path / "a") == tree(tmp_path / "b")
    assert sorted(tree(tmp_path / "b")) == ["config.yaml", "export.json", "shard-00000.tar", "shard-00001.tar",
                                            "shard-00002.tar"]


class Killed(BaseException):
    """Stands for the process being interrupted (not an Exception, like KeyboardInterrupt)."""


def test_crash_while_writing_leaves_no_partial_sequence_and_resume_completes(tmp_path, monkeypatch):
    ds = tiny_dataset(seed=2)
    writes = []
    real_write = export_module._write_file

    def failing_write(path, data):
        if len(writes) == 2 + len(SEQUENCE_FILES) + 3:  # export.json, config.yaml, sequence 0, 3 files of sequence 1
            raise Killed
        writes.append(path)
        real_write(path, data)

    monkeypatch.setattr(export_module, "_write_file", failing_write)
    with pytest.raises(Killed):
        export_dataset(ds, tmp_path / "a", count=4, progress=False)
    assert sorted(p.name for p in (tmp_path / "a").iterdir()) == [".export.lock", "000000", "config.yaml",
                                                                   "export.json"]
    assert {p.name for p in (tmp_path / "a" / "000000").iterdir()} == SEQUENCE_FILES
    assert any(".tmp-000001" in str(path) for path in writes)  # it did crash inside sequence 1

    monkeypatch.setattr(export_module, "_write_file", real_write)
    summary = export_dataset(ds, tmp_path / "a", count=4, progress=False)
    assert summary.written == (1, 2, 3) and summary.present == 1
    export_dataset(ds, tmp_path / "b", count=4, progress=False)
    assert tree(tmp_path / "a") == tree(tmp_path / "b")


def test_crash_while_rendering_a_shard_keeps_the_previous_shard_file(tmp_path, monkeypatch):
    ds = tiny_dataset(seed=3)
    export_dataset(ds, tmp_path, count=1, shards=3, progress=False)
    before = tree(tmp_path)
    real_record = export_module._record

    def failing_record(dataset, index):
        if index == 2:
            raise Killed
        return real_record(dataset, index)

    monkeypatch.setattr(export_module, "_record", failing_record)
    with pytest.raises(Killed):
        export_dataset(ds, tmp_path, count=3, shards=3, progress=False)
    assert tree(tmp_path) == before  # shard 0 still holds sequence 0 only, no temporary file
    monkeypatch.setattr(export_module, "_record", real_record)
    assert export_dataset(ds, tmp_path, count=3, shards=3, progress=False).written == (1, 2)
    assert ExportedDataset(tmp_path).indices == [0, 1, 2]


def test_killed_export_resumes(tmp_path):
    """``kill -9`` in the middle of an export: every sequence folder present is complete, and a rerun
    removes the temporary folder and writes exactly the missing sequences."""
    out = tmp_path / "out"
    command = [sys.executable, "-m", "sidar_torch", "export", "--out", str(out), "--count", "40", "--seed", "4",
               "--no-progress", "--set", "image_size=[24,32]", "--set", "n_views=2", "--set", "shadow_map_size=256"]
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 120
        while not (out / "000002").exists():
            assert process.poll() is None, process.stderr.read().decode()
            assert time.monotonic() < deadline, "the export did not write 3 sequences in 120 s"
            time.sleep(0.05)
    finally:
        if process.poll() is None:
            os.kill(process.pid, signal.SIGKILL)
        process.wait()
        process.stderr.close()
    assert process.returncode == -signal.SIGKILL
    done = sorted(p.name for p in out.iterdir() if export_module.SEQUENCE_NAME.match(p.name))
    assert 3 <= len(done) < 40
    for name in done:
        assert {p.name for p in (out / name).iterdir()} == SEQUENCE_FILES, name
    # What a kill while writing leaves (the kill above most likely hit rendering): a partial temporary folder.
    stale = out / f".tmp-{len(done):06d}"
    stale.mkdir(exist_ok=True)
    (stale / "0.png").write_bytes(b"partial")
    ds = tiny_dataset(seed=4)
    summary = export_dataset(ds, out, count=len(done) + 2, progress=False)
    assert summary.written == (len(done), len(done) + 1) and summary.present == len(done)
    assert not list(out.glob(".tmp-*"))
    read = ExportedDataset(out)
    for k in (0, len(done) - 1, len(done)):
        assert_same_sample(read[k], ds.sample(k))


def test_export_refuses_other_settings_foreign_folders_concurrent_writers_and_bad_arguments(tmp_path):
    ds = tiny_dataset(seed=0)
    export_dataset(ds, tmp_path / "a", count=1, progress=False)
    with pytest.raises(ValueError, match=r"seed: 0 there, 1 now"):
        export_dataset(tiny_dataset(seed=1), tmp_path / "a", count=1, progress=False)
    with pytest.raises(ValueError, match=r"config.n_views: 2 there, 3 now"):
        export_dataset(tiny_dataset(n_views=3), tmp_path / "a", count=1, progress=False)
    with pytest.raises(ValueError, match=r"layout: 'folders' there, 'shards' now"):
        export_dataset(ds, tmp_path / "a", count=1, shards=4, progress=False)
    (tmp_path / "b").mkdir()
    (tmp_path / "b" / "notes.txt").write_text("mine")
    with pytest.raises(ValueError, match=r"not empty and holds no export.json"):
        export_dataset(ds, tmp_path / "b", count=1, progress=False)
    with pytest.raises(NotADirectoryError, match="notes.txt"):
        export_dataset(ds, tmp_path / "b" / "notes.txt", count=1, progress=False)
    with pytest.raises(TypeError, match="dataset: expected a SidarDataset"):
        export_dataset([ds.sample(0)], tmp_path / "c", count=1)
    for kwargs, match in (({"count": 0}, "count"), ({"count": 1, "start": -1}, "start"),
                          ({"count": 1, "shards": 0}, "shards"), ({"count": 1, "workers": -1}, "workers")):
        with pytest.raises(ValueError, match=match):
            export_dataset(ds, tmp_path / "c", **kwargs)

    import fcntl

    with open(tmp_path / "a" / export_module.LOCK, "a") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        with pytest.raises(RuntimeError, match="another export is writing"):
            export_dataset(ds, tmp_path / "a", count=2, progress=False)
    assert export_dataset(ds, tmp_path / "a", count=2, progress=False).written == (1,)


def test_export_refuses_samples_that_pngs_would_change(tmp_path):
    class Brighter(SidarDataset):
        def sample(self, index):
            sample = super().sample(index)
            sample["images"] = sample["images"] * 0.999
            return sample

    with pytest.raises(ValueError, match=r"sample 0: images: expected 8-bit values"):
        export_dataset(Brighter(config=load_config("misaligned", **TINY)), tmp_path, count=1, progress=False)
    assert not list(tmp_path.glob("0*")) and not list(tmp_path.glob(".tmp-*"))


def test_reader_errors(tmp_path):
    with pytest.raises(FileNotFoundError, match="no export folder"):
        ExportedDataset(tmp_path / "missing")
    with pytest.raises(ValueError, match="not a sidar_torch export"):
        ExportedDataset(tmp_path)
    export_dataset(tiny_dataset(), tmp_path / "a", count=1, progress=False)
    read = ExportedDataset(tmp_path / "a")
    for k in (1, -2, 0.0, True):
        with pytest.raises(IndexError):
            read[k]
    (tmp_path / "a" / "000000" / "gt.png").unlink()
    with pytest.raises(FileNotFoundError, match="gt.png"):
        read[0]


def test_cli_export_with_overrides_and_progress(tmp_path, capsys):
    out = tmp_path / "out"
    cli.main(["export", "--out", str(out), "--count", "2", "--seed", "3", "--set", "image_size=[24,32]",
              "--set", "n_views=2", "--set", "shadow_map_size=256"])
    captured = capsys.readouterr()
    assert "export: 2/2 sequences" in captured.err and "wrote 2 sequences" in captured.out
    read = ExportedDataset(out)
    ds = tiny_dataset(seed=3)
    assert read.config == ds.config.to_dict()
    for k in range(2):
        assert_same_sample(read[k], ds.sample(k))
    with pytest.raises(SystemExit, match="export: count: expected an integer >= 1, got 0"):
        cli.main(["export", "--out", str(tmp_path / "x"), "--count", "0"])
    with pytest.raises(SystemExit, match="export: .*seed: 3 there, 0 now"):
        cli.main(["export", "--out", str(out), "--count", "2", "--set", "image_size=[24,32]", "--set", "n_views=2",
                  "--set", "shadow_map_size=256"])
    with pytest.raises(SystemExit, match="unknown config override"):
        cli.main(["export", "--out", str(tmp_path / "y"), "--count", "1", "--set", "n_veiws=2"])


def test_every_command_line_option_has_help():
    parser = cli._parser()
    commands = next(action for action in parser._actions if action.dest == "command")
    assert set(commands.choices) == {"preview", "export", "schema"}  # measurements live in benchmarks/
    for name, sub in commands.choices.items():
        for action in sub._actions:
            assert action.help and action.help.strip(), f"{name} {action.option_strings}: no help text"
    with pytest.raises(SystemExit) as exit_info:
        cli.main(["export", "--help"])
    assert exit_info.value.code == 0
