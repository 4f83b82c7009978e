"""Export and its reader under faults and bad input (issue 25): a user's files are never deleted,
an interrupted manifest resumes, any file name exports, a damaged shard is named and rewritten,
the reader reads only bounded regular files inside the export, a tampered manifest names its field."""

import errno
import hashlib
import json
import os
import re
import resource
import signal
import subprocess
import sys
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from sidar_torch import ExportedDataset, SidarDataset, export_dataset, load_config
from sidar_torch.io import files
from sidar_torch.io.reader import entry_size_limit

from conftest import TINY
from hang_guard import CHILD_WALL_SECONDS, cap_cpu
from test_export import tiny_dataset, tree

pytestmark = pytest.mark.gl  # renders


@contextmanager
def deadline(seconds):
    """Fail (instead of hanging) if the block takes longer than ``seconds``."""
    def expire(*_):
        raise TimeoutError(f"took longer than {seconds} s")

    previous = signal.signal(signal.SIGALRM, expire)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


# --------------------------------------------------------------------------- a user's files


USERS_FILES = {".tmp-backup": "folder", ".tmp-notes.txt": "file", files.LOCK: "file"}


def make_users_file(folder, name):
    if USERS_FILES[name] == "folder":
        (folder / name).mkdir(parents=True)
        (folder / name / "d").write_text("x")
    else:
        folder.mkdir(parents=True, exist_ok=True)
        (folder / name).write_text("x")


@pytest.mark.parametrize("name", list(USERS_FILES))
def test_export_refuses_a_folder_holding_a_users_file_and_keeps_it(tmp_path, name):
    """Issue 25 item 3: ``.tmp-*`` and ``.export.lock`` of the user's made a folder look empty, and
    the export deleted them."""
    out = tmp_path / "o"
    make_users_file(out, name)
    before = tree(tmp_path)
    with pytest.raises(ValueError, match=rf"not empty.*{name}|{name}.*not the lock file"):
        export_dataset(tiny_dataset(), out, count=1, progress=False)
    assert tree(tmp_path) == before and (out / name).exists()


@pytest.mark.parametrize("name", [".tmp-backup", ".tmp-notes.txt"])
def test_a_rerun_into_an_export_keeps_a_users_file(tmp_path, name):
    out = tmp_path / "o"
    export_dataset(tiny_dataset(), out, count=1, progress=False)
    make_users_file(out, name)
    assert export_dataset(tiny_dataset(), out, count=2, progress=False).written == (1,)
    assert (out / name).exists() and ExportedDataset(out).indices == [0, 1]


def test_a_killed_runs_own_temporaries_and_lock_are_removed(tmp_path):
    out = tmp_path / "o"
    export_dataset(tiny_dataset(), out, count=1, progress=False)
    (out / ".tmp-sidar-000001").mkdir()
    (out / ".tmp-sidar-000001" / "0.png").write_bytes(b"partial")
    (out / ".tmp-sidar-shard-00000.tar").write_bytes(b"partial")
    (out / files.LOCK).write_bytes(files.LOCK_MARKER)  # a kill -9 leaves the lock file
    assert export_dataset(tiny_dataset(), out, count=2, progress=False).written == (1,)
    assert sorted(p.name for p in out.iterdir()) == ["000000", "000001", "config.yaml", "export.json"]


# --------------------------------------------------------------------------- an interrupted manifest


@pytest.mark.parametrize("failing_write", [0, 1], ids=["first-manifest-file", "second-manifest-file"])
@pytest.mark.parametrize("fault", ["disk-full", "kill"])
def test_an_interruption_while_writing_the_manifest_leaves_a_folder_the_same_call_resumes(
        tmp_path, monkeypatch, failing_write, fault):
    """Issue 25 item 5: a full disk (or a kill) between ``config.yaml`` and ``export.json`` left
    ``config.yaml`` and ``.tmp-export.json``, and the same command was refused."""
    real_write, writes = files.write_file, []

    def write(path, data):
        if len(writes) == failing_write:
            if fault == "kill":
                raise KeyboardInterrupt  # stands for the process dying here
            real_write(path, data[:len(data) // 2])  # what fits on the disk
            raise OSError(errno.ENOSPC, "No space left on device", str(path))
        writes.append(path)
        real_write(path, data)

    monkeypatch.setattr(files, "write_file", write)
    with pytest.raises((OSError, KeyboardInterrupt)):
        export_dataset(tiny_dataset(), tmp_path / "a", count=2, progress=False)
    monkeypatch.setattr(files, "write_file", real_write)
    assert export_dataset(tiny_dataset(), tmp_path / "a", count=2, progress=False).written == (0, 1)
    export_dataset(tiny_dataset(), tmp_path / "b", count=2, progress=False)
    assert tree(tmp_path / "a") == tree(tmp_path / "b")


# --------------------------------------------------------------------------- any file name


def test_a_source_with_a_file_name_that_is_not_utf8_exports(tmp_path):
    """Issue 25 item 6: ``'utf-8' codec can't encode ... surrogates not allowed`` (the paths' hash)."""
    source = tmp_path / "paintings"
    source.mkdir()
    name = os.fsdecode(b"\xff.png")
    rng = np.random.default_rng(0)
    Image.fromarray(rng.integers(0, 256, (40, 50, 3), dtype=np.uint8)).save(source / name)
    dataset = SidarDataset(source=str(source), config=load_config("misaligned", **TINY))
    export_dataset(dataset, tmp_path / "out", count=1, progress=False)
    recorded = json.loads((tmp_path / "out" / "export.json").read_text())["source"]
    assert recorded["first_path"] == str(source / name)
    assert recorded["paths_sha256"] == hashlib.sha256(os.fsencode(source / name)).hexdigest()
    assert ExportedDataset(tmp_path / "out").indices == [0]
    assert export_dataset(dataset, tmp_path / "out", count=1, progress=False).present == 1  # the rerun matches


# --------------------------------------------------------------------------- damaged shards


@pytest.mark.parametrize("cut", ["half", "empty", "inside-an-entry", "no-end-marker"])
def test_a_damaged_shard_is_named_by_the_reader_and_rewritten_by_a_rerun(tmp_path, cut):
    """Issue 25 item 6: a truncated shard gave ``tarfile.ReadError`` naming nothing, and a rerun
    crashed until it was deleted by hand."""
    out, reference = tmp_path / "out", tmp_path / "reference"
    export_dataset(tiny_dataset(), reference, count=3, shard_size=2, progress=False)
    export_dataset(tiny_dataset(), out, count=3, shard_size=2, progress=False)
    shard = out / "shard-00000.tar"
    data = shard.read_bytes()
    end_of_entries = -(-len(data.rstrip(b"\0")) // 512) * 512
    keep = {"half": len(data) // 2, "empty": 0, "inside-an-entry": data.rindex(b"cameras.json") + 600,
            "no-end-marker": end_of_entries}[cut]
    shard.write_bytes(data[:keep])
    with pytest.raises(ValueError, match=r"shard-00000\.tar'?: damaged shard"):
        ExportedDataset(out)
    summary = export_dataset(tiny_dataset(), out, count=3, shard_size=2, progress=False)
    assert 1 in summary.written and 2 not in summary.written
    assert tree(out) == tree(reference)


# --------------------------------------------------------------------------- what the reader reads


def replace_with(path, kind, tmp_path):
    """Replace the file ``path`` of an export with a FIFO, a link to a device, a large file, ..."""
    path.unlink()
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "dev-zero":
        path.symlink_to("/dev/zero")
    elif kind == "outside":
        (tmp_path / "elsewhere.png").write_bytes(b"\x89PNG")
        path.symlink_to(tmp_path / "elsewhere.png")
    elif kind == "too-large":
        path.write_bytes(bytes(entry_size_limit({"image_size": TINY["image_size"], "n_views": 2}) + 1))
    elif kind == "png-bomb":  # a PNG header claiming 100000 x 100000 pixels
        buffer = Path(tmp_path / "bomb.png")
        Image.new("L", (32, 24)).save(buffer)
        header = bytearray(buffer.read_bytes())
        header[16:24] = (100000).to_bytes(4, "big") * 2
        path.write_bytes(bytes(header))


def read_in_a_capped_process(out):
    """stderr of ``ExportedDataset(out)[0]`` run in a child limited to 4 GiB of address space and
    60 s of CPU time, so that a reader that reads without bound cannot take the machine's memory."""
    cap = 4 * 2**30

    def limits():
        resource.setrlimit(resource.RLIMIT_AS, (cap, cap))
        cap_cpu(60)()

    result = subprocess.run([sys.executable, "-c", "import sys; from sidar_torch import ExportedDataset\n"
                             "ExportedDataset(sys.argv[1])[0]", str(out)],
                            preexec_fn=limits, capture_output=True, text=True, timeout=CHILD_WALL_SECONDS)
    assert result.returncode != 0
    return result.stderr


def test_the_reader_refuses_a_link_to_dev_zero(tmp_path):
    """Issue 25 item 6: the reader read ``/dev/zero`` without bound (here in a child under a memory cap)."""
    out = tmp_path / "out"
    export_dataset(tiny_dataset(), out, count=1, progress=False)
    replace_with(out / "000000" / "0.png", "dev-zero", tmp_path)
    assert re.search(r"ValueError: .*000000/0\.png'?: leads outside the export", read_in_a_capped_process(out))


@pytest.mark.parametrize("kind, message", [
    ("fifo", "expected a regular file, got a FIFO"),
    ("outside", "leads outside the export"),
    ("too-large", "larger than"),
    ("png-bomb", r"not a PNG of 24 x 32 pixels .* says \(100000, 100000\)"),
])
def test_the_reader_reads_only_bounded_regular_files_inside_the_export(tmp_path, kind, message):
    """Issue 25 item 6: the reader hung on a FIFO named ``0.png`` and read ``/dev/zero`` without bound."""
    out = tmp_path / "out"
    export_dataset(tiny_dataset(), out, count=1, progress=False)
    replace_with(out / "000000" / "0.png", kind, tmp_path)
    with deadline(20), pytest.raises(ValueError, match=message) as error:
        ExportedDataset(out)[0]
    assert "0.png" in str(error.value)


def test_the_reader_refuses_a_sequence_folder_linked_from_outside_and_a_device_as_a_shard(tmp_path):
    out = tmp_path / "out"
    export_dataset(tiny_dataset(), out, count=1, progress=False)
    (out / "000000").rename(tmp_path / "elsewhere")
    (out / "000000").symlink_to(tmp_path / "elsewhere")
    with pytest.raises(ValueError, match=r"000000/cameras.json'?: leads outside the export"):
        ExportedDataset(out)[0]

    shards = tmp_path / "shards"
    export_dataset(tiny_dataset(), shards, count=1, shard_size=2, progress=False)
    (shards / "shard-00000.tar").unlink()
    os.mkfifo(shards / "shard-00000.tar")
    with deadline(20), pytest.raises(ValueError, match=r"shard-00000\.tar'?: not a regular file: expected a regular file, got a FIFO"):
        ExportedDataset(shards)


# --------------------------------------------------------------------------- tampered manifests


def tamper(manifest):
    """Edits of ``export.json``: name -> (edit of the decoded dict, or raw bytes; the field named)."""
    return {
        "no-config": ({k: v for k, v in manifest.items() if k != "config"}, "field 'config'"),
        "layout-foo": ({**manifest, "layout": "foo"}, "field 'layout': expected one of"),
        "config-null": ({**manifest, "config": None}, "field 'config': expected a JSON object"),
        "list": ([manifest], r"field '\(top level\)'"),
        "seed-text": ({**manifest, "seed": "0"}, "field 'seed'"),
        "shard-size-for-folders": ({**manifest, "shard_size": 2}, "field 'shard_size'"),
        "no-image-size": ({**manifest, "config": {**manifest["config"], "image_size": None}},
                          "field 'config.image_size'"),
        "geometry-dtype": ({**manifest, "config": {**manifest["config"], "geometry_dtype": "int8"}},
                           "field 'config.geometry_dtype'"),
        "lens-model": ({**manifest, "config": {**manifest["config"], "lens_model": "fisheye"}},
                       "field 'config.lens_model'"),
        "maps-switch": ({**manifest, "config": {**manifest["config"], "distortion_map_output": "yes"}},
                        "field 'config.distortion_map_output'"),
        "binary": (b"\xff\xfe\x00garbage", "not UTF-8"),
        "long-integer": (json.dumps(manifest).replace('"seed": 0', '"seed": ' + "9" * 5000).encode(),
                         "an integer of 5000 digits"),  # issue 34 item 4: a ValueError naming no file
        "deep": (b"[" * 100000, "not valid JSON"),
    }


@pytest.mark.parametrize("case", list(tamper({"config": {}})))
def test_a_tampered_manifest_is_a_value_error_naming_the_file_and_the_field(tmp_path, case):
    """Issue 25 item 6: ``KeyError``/``AttributeError``, and ``layout: "foo"`` opened with 0 items."""
    out = tmp_path / "out"
    export_dataset(tiny_dataset(), out, count=1, progress=False)
    edit, named = tamper(json.loads((out / "export.json").read_text()))[case]
    (out / "export.json").write_bytes(edit if isinstance(edit, bytes) else json.dumps(edit).encode())
    with pytest.raises(ValueError, match=named) as error:
        ExportedDataset(out)
    assert "export.json" in str(error.value)
    with pytest.raises(ValueError, match=named):  # and a rerun of the export says the same
        export_dataset(tiny_dataset(), out, count=1, progress=False)
