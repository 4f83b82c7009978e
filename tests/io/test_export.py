"""Export and its reader: byte-identical round trips, both layouts, resuming after a crash or a kill,
refusing to mix settings, the command line."""

import json
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
from sidar_torch.io import files, layout
from sidar_torch.sample import sequence_homographies

import export_digests
from conftest import TINY, alive, assert_same_sample, child_pids
from recorded import mismatches, rasteriser_mismatch

pytestmark = pytest.mark.gl  # renders

SEQUENCE_FILES = {"0.png", "1.png", "0-m.png", "1-m.png", "gt.png", "H_0_1.mat", "H_1_0.mat", "cameras.json"}


def tiny_dataset(seed=0, **overrides):
    return SidarDataset(config=load_config("misaligned", **{**TINY, **overrides}), seed=seed)


def tree(path):
    """``{relative path: bytes}`` of every file under ``path`` but the lock file."""
    return {str(p.relative_to(path)): p.read_bytes() for p in sorted(Path(path).rglob("*"))
            if p.is_file() and p.name != files.LOCK}



def wait_for_three_sequences(process: subprocess.Popen, out: Path) -> None:
    """Wait (up to 120 s) until the export ``process`` has written sequence 2 into ``out``; fail
    with its stderr if it exits first."""
    deadline = time.monotonic() + 120
    while not (out / "000002").exists():
        assert process.poll() is None, process.stderr.read().decode()
        assert time.monotonic() < deadline, "the export did not write 3 sequences in 120 s"
        time.sleep(0.05)

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


@pytest.mark.parametrize("layout", ["folders", "shards"])
def test_depth_and_flow_are_exported_as_float32_npy_files_and_read_back_exactly(tmp_path, layout):
    ds = tiny_dataset(seed=2, depth_output=True, flow_output=True, scene_per_view=False, n_occluders=(1, 2))
    export_dataset(ds, tmp_path, count=2, layout=layout, shards=1 if layout == "shards" else None, progress=False)
    read = ExportedDataset(tmp_path)
    for k in range(2):
        rendered = ds.sample(k)
        assert rendered["depth"].dtype == torch.float32
        assert_same_sample(read[k], rendered)
    if layout == "folders":
        depth = np.load(tmp_path / "000001" / "1-d.npy")
        assert depth.dtype == np.float32 and depth.shape == TINY["image_size"]
        assert np.array_equal(depth, ds.sample(1)["depth"][1, 0].numpy())
        flows = np.load(tmp_path / "000001" / "1-flow.npy")
        assert flows.dtype == np.float32 and flows.shape == (*TINY["image_size"], 2)
        np.save(tmp_path / "000001" / "1-d.npy", depth.astype(np.float64))
        with pytest.raises(ValueError, match=r"1-d.npy': its header declares float64 .* expected .* of float32"):
            ExportedDataset(tmp_path)[1]


def test_shards_round_trip_resume_and_match_an_uninterrupted_export(tmp_path):
    ds = tiny_dataset(seed=1)
    export_dataset(ds, tmp_path / "a", count=3, start=1, shard_size=2, progress=False)
    with tarfile.open(tmp_path / "a" / "shard-00001.tar") as tar:
        names = tar.getnames()
    assert names[:2] == ["000002.0.png", "000002.0-m.png"] and "000003.homographies.npy" in names
    read = ExportedDataset(tmp_path / "a")
    assert read.layout == "shards" and read.indices == [1, 2, 3]
    for k, index in enumerate(read.indices):
        assert_same_sample(read[k], ds.sample(index))

    # More sequences into the same folder: only 0 and 4 are rendered, shard 0 keeps sequence 1's bytes.
    summary = export_dataset(ds, tmp_path / "a", count=5, shard_size=2, progress=False)
    assert summary.written == (0, 4) and summary.present == 3
    export_dataset(ds, tmp_path / "b", count=5, shard_size=2, workers=2, progress=False)
    assert tree(tmp_path / "a") == tree(tmp_path / "b")
    assert sorted(tree(tmp_path / "b")) == ["config.yaml", "export.json", "shard-00000.tar", "shard-00001.tar",
                                            "shard-00002.tar"]


class Killed(BaseException):
    """Stands for the process being interrupted (not an Exception, like KeyboardInterrupt)."""


def test_crash_while_writing_leaves_no_partial_sequence_and_resume_completes(tmp_path, monkeypatch):
    ds = tiny_dataset(seed=2)
    writes = []
    real_write = files.write_file

    def failing_write(path, data):
        if len(writes) == 2 + len(SEQUENCE_FILES) + 3:  # export.json, config.yaml, sequence 0, 3 files of sequence 1
            raise Killed
        writes.append(path)
        real_write(path, data)

    monkeypatch.setattr(files, "write_file", failing_write)
    with pytest.raises(Killed):
        export_dataset(ds, tmp_path / "a", count=4, progress=False)
    assert sorted(p.name for p in (tmp_path / "a").iterdir()) == ["000000", "config.yaml", "export.json"]
    assert {p.name for p in (tmp_path / "a" / "000000").iterdir()} == SEQUENCE_FILES
    assert any(".tmp-sidar-000001" in str(path) for path in writes)  # it did crash inside sequence 1

    monkeypatch.setattr(files, "write_file", real_write)
    summary = export_dataset(ds, tmp_path / "a", count=4, progress=False)
    assert summary.written == (1, 2, 3) and summary.present == 1
    export_dataset(ds, tmp_path / "b", count=4, progress=False)
    assert tree(tmp_path / "a") == tree(tmp_path / "b")


def test_crash_while_rendering_a_shard_keeps_the_previous_shard_file(tmp_path, monkeypatch):
    ds = tiny_dataset(seed=3)
    export_dataset(ds, tmp_path, count=1, shard_size=3, progress=False)
    before = tree(tmp_path)
    real_render = SidarDataset.sample_arrays

    def failing_render(dataset, index):
        if index == 2:
            raise Killed
        return real_render(dataset, index)

    monkeypatch.setattr(SidarDataset, "sample_arrays", failing_render)
    with pytest.raises(Killed):
        export_dataset(ds, tmp_path, count=3, shard_size=3, progress=False)
    assert tree(tmp_path) == before  # shard 0 still holds sequence 0 only, no temporary file
    monkeypatch.setattr(SidarDataset, "sample_arrays", real_render)
    assert export_dataset(ds, tmp_path, count=3, shard_size=3, progress=False).written == (1, 2)
    assert ExportedDataset(tmp_path).indices == [0, 1, 2]


def test_killed_export_resumes(tmp_path):
    """``kill -9`` in the middle of an export: every sequence folder present is complete, and a rerun
    removes the temporary folder and writes exactly the missing sequences."""
    out = tmp_path / "out"
    command = [sys.executable, "-m", "sidar_torch", "export", "--out", str(out), "--count", "40", "--seed", "4",
               "--no-progress", "--set", "image_size=[24,32]", "--set", "n_views=2", "--set", "shadow_map_size=256"]
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        wait_for_three_sequences(process, out)
    finally:
        if process.poll() is None:
            os.kill(process.pid, signal.SIGKILL)
        process.wait()
        process.stderr.close()
    assert process.returncode == -signal.SIGKILL
    done = sorted(p.name for p in out.iterdir() if layout.SEQUENCE_NAME.match(p.name))
    assert 3 <= len(done) < 40
    for name in done:
        assert {p.name for p in (out / name).iterdir()} == SEQUENCE_FILES, name
    # What a kill while writing leaves (the kill above most likely hit rendering): a partial temporary folder.
    stale = out / f".tmp-sidar-{len(done):06d}"
    stale.mkdir(exist_ok=True)
    (stale / "0.png").write_bytes(b"partial")
    ds = tiny_dataset(seed=4)
    summary = export_dataset(ds, out, count=len(done) + 2, progress=False)
    assert summary.written == (len(done), len(done) + 1) and summary.present == len(done)
    assert not list(out.glob(".tmp-sidar-*"))
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
        export_dataset(ds, tmp_path / "a", count=1, shard_size=4, progress=False)
    (tmp_path / "b").mkdir()
    (tmp_path / "b" / "notes.txt").write_text("mine")
    with pytest.raises(ValueError, match=r"not empty and holds no export.json"):
        export_dataset(ds, tmp_path / "b", count=1, progress=False)
    with pytest.raises(NotADirectoryError, match="notes.txt"):
        export_dataset(ds, tmp_path / "b" / "notes.txt", count=1, progress=False)
    with pytest.raises(TypeError, match="dataset: expected a SidarDataset"):
        export_dataset([ds.sample(0)], tmp_path / "c", count=1)
    for kwargs, match in (({"count": 0}, "count"), ({"count": 1, "start": -1}, "start"),
                          ({"count": 1, "shard_size": 0}, "shard_size"), ({"count": 1, "workers": -1}, "workers"),
                          ({"count": 1, "workers": 257}, "workers: expected an integer from 0 to 256")):
        with pytest.raises(ValueError, match=match):
            export_dataset(ds, tmp_path / "c", **kwargs)

    assert not (tmp_path / "b" / files.LOCK).exists()  # a refused run leaves no lock file behind
    holder = subprocess.Popen([sys.executable, "-c", "import fcntl, os, sys, time\n"  # an export's lock, held
                               f"fd = os.open({str(tmp_path / 'a' / files.LOCK)!r}, os.O_RDWR | os.O_CREAT)\n"
                               f"os.write(fd, {files.LOCK_MARKER!r})\n"
                               "fcntl.lockf(fd, fcntl.LOCK_EX); print('locked', flush=True); time.sleep(60)"],
                              stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline() == "locked\n"
        with pytest.raises(RuntimeError, match="another export is writing"):
            export_dataset(ds, tmp_path / "a", count=2, progress=False)
    finally:
        holder.kill()
        holder.wait()
        holder.stdout.close()
    assert export_dataset(ds, tmp_path / "a", count=2, progress=False).written == (1,)
    assert not (tmp_path / "a" / files.LOCK).exists()


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
    with pytest.raises(ValueError, match=r"sequence 000000 of .*: a file is missing: .*000000/gt.png' does not exist"):
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
    for argv, message in (
            (["--out", str(tmp_path / "x"), "--count", "0"], "count: expected an integer >= 1, got 0"),
            (["--out", str(out), "--count", "2", "--set", "image_size=[24,32]", "--set", "n_views=2",
              "--set", "shadow_map_size=256"], "seed: 3 there, 0 now"),
            (["--out", str(tmp_path / "y"), "--count", "1", "--set", "n_veiws=2"], "unknown config override")):
        with pytest.raises(SystemExit) as exit_info:
            cli.main(["export", *argv])
        assert exit_info.value.code == 2
        err = capsys.readouterr().err
        assert err.startswith("sidar_torch export: ") and message in err and err.count("\n") == 1, err


@pytest.mark.parametrize("argv, message", [
    (["--config", "no_such_preset"], "not a preset"),
    (["--config", "missing.yaml"], "missing.yaml"),
    (["--set", "n_views"], "expected key=value"),
    (["--set", "fov_deg=[40, 60"], "the value is not YAML"),
    (["--set", "n_veiws=2"], "did you mean"),
    (["--source", "/no/such/folder"], "/no/such/folder"),
    (["--samples", "0"], "--samples 0"),
], ids=["preset", "yaml-path", "set-no-equals", "set-bad-yaml", "set-unknown", "source", "samples"])
def test_every_command_prints_one_line_for_a_user_mistake_and_exits_2(argv, message, tmp_path):
    """Issue 13 item 4: ``preview`` (like ``export``) prints one line, no traceback, exit code 2."""
    result = subprocess.run([sys.executable, "-m", "sidar_torch", "preview", "--out", str(tmp_path / "p.png"), *argv],
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 2, result.stderr
    assert result.stderr.startswith("sidar_torch preview: ") and message in result.stderr, result.stderr
    assert result.stderr.count("\n") == 1 and "Traceback" not in result.stderr


def test_every_command_line_option_has_help():
    parser = cli._parser()
    commands = next(action for action in parser._actions if action.dest == "command")
    assert set(commands.choices) == {"preview", "export", "schema", "evaluate"}  # measurements live in benchmarks/
    for name, sub in commands.choices.items():
        for action in sub._actions:
            assert action.help and action.help.strip(), f"{name} {action.option_strings}: no help text"
    with pytest.raises(SystemExit) as exit_info:
        cli.main(["export", "--help"])
    assert exit_info.value.code == 0


def test_exported_files_match_the_records_stored_on_main():
    """Every file of a folder and a shard export (opacities on) is what the export of ``main`` wrote
    (see ``export_digests.py``): manifests byte for byte, geometry files within ``recorded.py``'s
    tolerances, pixel files byte for byte where the rasteriser is the recorded one."""
    stored = json.loads(export_digests.STORE.read_text())
    now = export_digests.current_records()
    mismatch = rasteriser_mismatch(stored["recorded_with"])  # after rendering: it asks the current context
    differences = []
    for kind, expected in stored["exports"].items():
        assert sorted(now[kind]) == sorted(expected), f"{kind}: other files or entries than on main"
        differences += [difference for name, record in expected.items()
                        if mismatch is None or not export_digests.is_pixel_file(name)
                        for difference in mismatches(f"{kind}: {name}", record, now[kind][name])]
    assert not differences, "\n".join(differences)
    if mismatch is not None:
        pytest.skip(f"pixel files not compared: {mismatch}")


def test_reader_names_the_field_a_damaged_file_breaks(tmp_path):
    export_dataset(tiny_dataset(), tmp_path, count=1, progress=False)
    Image.new("RGB", (32, 24)).save(tmp_path / "000000" / "1-m.png")  # a mask is 8-bit grey
    with pytest.raises(ValueError, match=r"000000/1-m\.png'?: expected an 8-bit grey PNG, its header says bit depth 8, "
                                         r"colour type 2"):
        ExportedDataset(tmp_path)[0]


@pytest.mark.parametrize("shard_size", [None, 2])
def test_reader_returns_float64_geometry_when_the_set_was_rendered_so(tmp_path, shard_size):
    ds = tiny_dataset(seed=6, geometry_dtype="float64")
    export_dataset(ds, tmp_path, count=2, shard_size=shard_size, progress=False)
    read = ExportedDataset(tmp_path)
    assert read.config["geometry_dtype"] == "float64"
    for k in range(2):
        sample = read[k]
        assert sample["homographies"].dtype == torch.float64 and sample["K"].dtype == torch.float64
        assert_same_sample(sample, ds.sample(k))


@pytest.mark.slow
@pytest.mark.parametrize("signal_number", [signal.SIGKILL, signal.SIGTERM], ids=["kill-9", "sigterm"])
def test_export_with_workers_killed_leaves_no_process_and_resumes_to_the_same_bytes(tmp_path, signal_number):
    """Issue 13 items 1 and 10: killing the export's main process while two DataLoader workers render
    leaves no worker alive (they used to block forever holding the inherited lock), and the rerun
    resumes to a set byte-identical to an uninterrupted export."""
    out, reference = tmp_path / "out", tmp_path / "reference"
    settings = ["--seed", "4", "--no-progress", "--set", "image_size=[24,32]", "--set", "n_views=2",
                "--set", "shadow_map_size=256"]
    command = [sys.executable, "-m", "sidar_torch", "export", "--out", str(out), "--count", "30", "--workers", "2"]
    process = subprocess.Popen(command + settings, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        wait_for_three_sequences(process, out)
        workers = child_pids(process.pid)
        assert len(workers) >= 2, workers
    finally:
        if process.poll() is None:
            os.kill(process.pid, signal_number)
        process.wait()
        process.stderr.close()
    deadline = time.monotonic() + 10
    while any(alive(pid) for pid in workers) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not [pid for pid in workers if alive(pid)], "workers of the killed export are still running"
    rerun = subprocess.run(command + settings, capture_output=True, text=True, timeout=300)
    assert rerun.returncode == 0, rerun.stderr[-2000:]
    subprocess.run([sys.executable, "-m", "sidar_torch", "export", "--out", str(reference), "--count", "30"]
                   + settings, check=True, capture_output=True, timeout=300)
    assert tree(out) == tree(reference)
    assert not (out / files.LOCK).exists()


def test_ctrl_c_prints_one_line_saying_how_far_it_got_and_the_same_command_resumes(tmp_path):
    """Issue 20 item 6: Ctrl-C printed a 40-line traceback ending inside PIL (exit -2)."""
    out = tmp_path / "out"
    command = [sys.executable, "-m", "sidar_torch", "export", "--out", str(out), "--count", "40", "--seed", "4",
               "--no-progress", "--set", "image_size=[24,32]", "--set", "n_views=2", "--set", "shadow_map_size=256"]
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        wait_for_three_sequences(process, out)
        os.kill(process.pid, signal.SIGINT)
        _, err = process.communicate(timeout=60)
    finally:
        if process.poll() is None:
            process.kill()
            process.communicate()
    done = sorted(p.name for p in out.iterdir() if layout.SEQUENCE_NAME.match(p.name))
    assert process.returncode == 130, err
    assert err == (f"sidar_torch export: interrupted after {len(done)} of 40 sequences; "
                   f"run the same command again to resume\n")
    assert not (out / files.LOCK).exists() and not list(out.glob(".tmp-sidar-*"))
    summary = export_dataset(tiny_dataset(seed=4), out, count=len(done) + 1, progress=False)
    assert summary.written == (len(done),) and summary.present == len(done)


def test_the_shard_size_option_and_its_old_name(tmp_path, capsys):
    """Issue 20 item 6: ``--shards 1000`` meant 1,000 sequences per shard (a webdataset user reads
    1,000 shards): the option is ``--shard-size``; ``--shards`` is refused naming it. The Python
    keyword ``shards=`` stays accepted as the older name of ``shard_size=``."""
    with pytest.raises(SystemExit) as exit_info:
        cli.main(["export", "--out", str(tmp_path / "x"), "--count", "1", "--shards", "1000"])
    assert exit_info.value.code == 2
    assert "--shards was renamed --shard-size" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()

    cli.main(["export", "--out", str(tmp_path / "cli"), "--count", "3", "--shard-size", "2", "--no-progress",
              "--set", "image_size=[24,32]", "--set", "n_views=2", "--set", "shadow_map_size=256"])
    assert sorted(p.name for p in (tmp_path / "cli").glob("*.tar")) == ["shard-00000.tar", "shard-00001.tar"]
    export_dataset(tiny_dataset(), tmp_path / "old-name", count=3, shards=2, progress=False)
    assert tree(tmp_path / "old-name") == tree(tmp_path / "cli")
    with pytest.raises(ValueError, match="shards=2: the older name of shard_size; pass shard_size only"):
        export_dataset(tiny_dataset(), tmp_path / "both", count=1, shard_size=2, shards=2, progress=False)


def test_a_first_ctrl_c_waits_for_the_next_sequence_and_a_second_stops_at_once():
    # A KeyboardInterrupt raised wherever SIGINT lands could land in ctypes' conversion of a GL
    # argument and come out as a ctypes.ArgumentError (a traceback, exit 1, seen in CI).
    from sidar_torch.io.export import ctrl_c_between

    before = signal.getsignal(signal.SIGINT)
    with ctrl_c_between() as check:
        check()  # nothing pressed: nothing raised
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(0.05)  # the handler has run: held, not raised
        with pytest.raises(KeyboardInterrupt):
            check()
        with pytest.raises(KeyboardInterrupt):
            os.kill(os.getpid(), signal.SIGINT)  # the second press
            time.sleep(1)
    assert signal.getsignal(signal.SIGINT) is before
