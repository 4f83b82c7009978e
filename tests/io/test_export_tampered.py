"""Issue 34 items 2 and 3: a tampered export. The reader takes every size from the files and the
package's bounds (the config's), never from the manifest alone, and every malformed file is a
``ValueError`` naming it, read in bounded memory: headers and declared shapes are checked before
anything of their size is decoded, inflated or allocated. The hostile files are built small here."""

import io
import json
import re
import shutil
import struct
import tarfile
import tracemalloc
import zlib

import numpy as np
import pytest
import scipy.io
from PIL import Image

from sidar_torch import ExportedDataset, export_dataset

from test_export import tiny_dataset

pytestmark = pytest.mark.gl  # renders (the exports the tests tamper with)

PEAK_LIMIT = 32 * 2**20
"""Most bytes the Python and NumPy allocations of reading a tampered TINY sequence may peak at (a
whole TINY sample takes a few kB; the hostile files below ask for 200 MB to 1e15 bytes)."""


@pytest.fixture(scope="module")
def exports(tmp_path_factory):
    """``{"folders": path, "shards": path}``: one TINY sequence exported in each layout, untouched."""
    root = tmp_path_factory.mktemp("tampered")
    export_dataset(tiny_dataset(), root / "folders", count=1, progress=False)
    export_dataset(tiny_dataset(), root / "shards", count=1, shard_size=1, progress=False)
    return {"folders": root / "folders", "shards": root / "shards"}


def copy_of(exports, layout, tmp_path):
    out = tmp_path / layout
    shutil.copytree(exports[layout], out)
    return out


def read_with_bounded_memory(out, item=True):
    """Open ``out`` (and read item 0 if ``item``) with NumPy's and Python's allocations traced;
    return the ``ValueError`` raised, asserting that the allocations peaked under :data:`PEAK_LIMIT`."""
    tracemalloc.start()
    try:
        with pytest.raises(ValueError) as error:
            dataset = ExportedDataset(out)
            if item:
                dataset[0]
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < PEAK_LIMIT, f"reading took {peak / 2**20:.0f} MiB before refusing: {error.value}"
    return str(error.value)


# --------------------------------------------------------------------------- the manifest's sizes


def png_header_of(size):
    """The bytes of an 8-bit grey PNG whose header says ``size`` ``(H, W)`` (its pixels: 24 x 32 of them)."""
    buffer = io.BytesIO()
    Image.new("L", (32, 24)).save(buffer, format="PNG")
    data = bytearray(buffer.getvalue())
    data[16:24] = struct.pack(">II", size[1], size[0])
    return bytes(data)


@pytest.mark.parametrize("config, named", [
    ({"image_size": [9400, 9400]}, r"config fields 'image_size' and 'n_views': .* 2 views of 9400 x 9400"),  # 6.58 GB
    ({"image_size": [100000, 100000]}, r"config field 'image_size': expected \(H, W\) with 1 <= H, W <= 16384"),
    ({"n_views": 10**12}, "config field 'n_views': expected 1 <= value <= 256"),  # OverflowError
    ({"n_views": 256, "image_size": [16384, 16384]}, "config fields 'image_size' and 'n_views'"),
])
@pytest.mark.parametrize("layout", ["folders", "shards"])
def test_a_manifest_asking_for_more_than_the_bounds_is_refused_before_anything_is_read(
        exports, tmp_path, layout, config, named):
    """Issue 34 item 2: ``image_size`` 9400 x 9400 with zero-filled PNGs of that size took 6.58 GB
    and 101 s; ``[100000, 100000]`` gave ``MemoryError``, ``n_views`` 10**12 ``OverflowError``."""
    out = copy_of(exports, layout, tmp_path)
    manifest = json.loads((out / "export.json").read_text())
    manifest["config"].update(config)
    (out / "export.json").write_text(json.dumps(manifest))
    if layout == "folders":  # PNGs whose headers agree with the manifest: only the bounds can refuse them
        for png in (out / "000000").glob("*.png"):
            png.write_bytes(png_header_of(manifest["config"]["image_size"]))
    message = read_with_bounded_memory(out, item=False)
    assert "export.json" in message and re.search(named, message), message


@pytest.mark.parametrize("layout", ["folders", "shards"])
def test_a_manifest_that_disagrees_with_the_files_names_the_file(exports, tmp_path, layout):
    """The manifest says 3 views of 24 x 48; the sequence's cameras hold 2 of 24 x 32."""
    for change, named in [({"n_views": 3}, r"cameras\.json.*2 views.*'n_views' is 3"),
                          ({"image_size": [24, 48]}, r"cameras\.json.*image_size \[24, 32\].*\[24, 48\]")]:
        out = copy_of(exports, layout, tmp_path / str(change))
        manifest = json.loads((out / "export.json").read_text())
        manifest["config"].update(change)
        (out / "export.json").write_text(json.dumps(manifest))
        assert re.search(named, read_with_bounded_memory(out))


# --------------------------------------------------------------------------- per-sequence files


def cameras_edits():
    return {
        "list": ([], "expected a JSON object"),  # TypeError
        "error-list": ({"homography_error": [1]}, "'homography_error': expected a number"),  # TypeError
        "error-bool": ({"homography_error": True}, "'homography_error': expected a number"),
        "K-text": ({"K": "eye"}, r"'K': expected \(2, 3, 3\) numbers"),
        "K-ragged": ({"K": [[[1, 0, 0]], [[0, 1, 0]]]}, r"'K': expected \(2, 3, 3\) numbers"),
        "t-strings": ({"t": [["0", "0", "1"], ["0", "0", "1"]]}, r"'t': expected \(2, 3\) numbers"),
        "no-R": ({"R": None}, r"'R': expected \(2, 3, 3\) numbers"),
    }


@pytest.mark.parametrize("case", list(cameras_edits()))
@pytest.mark.parametrize("layout", ["folders", "shards"])
def test_a_malformed_cameras_json_is_a_value_error_naming_it(exports, tmp_path, layout, case):
    """Issue 34 item 3: ``cameras.json`` holding ``[]`` or ``homography_error: [1]`` gave ``TypeError``."""
    out = copy_of(exports, layout, tmp_path)
    edit, named = cameras_edits()[case]

    def tampered(data):
        cameras = json.loads(data)
        return json.dumps(edit if isinstance(edit, list) else {**cameras, **edit}).encode()

    replace_entry(out, layout, "cameras.json", tampered)
    message = read_with_bounded_memory(out)
    assert "000000/cameras.json'" in message or "000000.cameras.json" in message, message
    assert re.search(named, message), message


def replace_entry(out, layout, name, change):
    """Replace entry ``name`` of sequence 0 of the export ``out`` by ``change(its bytes)``."""
    if layout == "folders":
        path = out / "000000" / name
        path.write_bytes(change(path.read_bytes()))
        return
    shard = out / "shard-00000.tar"
    with tarfile.open(shard) as tar:
        members = [(m, tar.extractfile(m).read()) for m in tar]
    with tarfile.open(shard, "w") as tar:
        for member, data in members:
            if member.name == f"000000.{name}":
                data = change(data)
            member.size = len(data)
            tar.addfile(member, io.BytesIO(data))


def npy_header_declaring(shape):
    """A ``.npy`` file whose header declares float64 ``shape`` and which holds 64 bytes of data."""
    buffer = io.BytesIO()
    np.lib.format.write_array_header_1_0(buffer, {"descr": "<f8", "fortran_order": False, "shape": shape})
    return buffer.getvalue() + bytes(64)


def mat_bomb(shape=(5000, 5000)):
    """A MATLAB 5 file of one compressed variable ``H`` of zeros of ``shape`` (200 MB at the default,
    about 200 kB compressed), built without holding its inflated bytes."""
    header = b"MATLAB 5.0 MAT-file".ljust(116) + bytes(8) + struct.pack("<H2s", 0x0100, b"IM")
    data_bytes = 8 * shape[0] * shape[1]
    matrix = (struct.pack("<II", 6, 8) + struct.pack("<II", 6, 0)          # array flags: double
              + struct.pack("<II", 5, 8) + struct.pack("<ii", *shape)      # dimensions
              + struct.pack("<HH", 1, 1) + b"H\0\0\0"                      # name, small data element
              + struct.pack("<II", 9, data_bytes))                         # real part: miDOUBLE
    compressor = zlib.compressobj(9)
    body = [compressor.compress(struct.pack("<II", 14, len(matrix) + data_bytes) + matrix)]
    zeros = bytes(2**20)
    for _ in range(data_bytes // len(zeros)):
        body.append(compressor.compress(zeros))
    body.append(compressor.compress(bytes(data_bytes % len(zeros))) + compressor.flush())
    compressed = b"".join(body)
    return header + struct.pack("<II", 15, len(compressed)) + compressed


def mat_of(**variables):
    buffer = io.BytesIO()
    scipy.io.savemat(buffer, variables)
    return buffer.getvalue()


def truncated(data):
    return data[:len(data) // 2]


FOLDER_FILES = {
    "png-truncated": ("0.png", truncated, "not a readable PNG"),  # OSError
    "png-not-a-png": ("0-m.png", lambda data: b"GIF89a" + bytes(100), "not a PNG"),
    "png-rgb-mask": ("0-m.png", lambda data: zeros_png((24, 32, 3)), "expected an 8-bit grey PNG"),
    "png-16-bit": ("gt.png", lambda data: zeros_png((24, 32), np.uint16), "expected an 8-bit RGB PNG"),
    "mat-without-H": ("H_0_1.mat", lambda data: mat_of(G=np.eye(3)), "no variable 'H'"),  # KeyError
    "mat-of-another-shape": ("H_1_0.mat", lambda data: mat_of(H=np.eye(4)), r"'H' of shape \(4, 4\)"),
    "mat-of-text": ("H_1_0.mat", lambda data: mat_of(H="abc"), "'H' of shape .*, class char"),
    "mat-truncated": ("H_0_1.mat", truncated, r"no variable 'H' \(it holds \[\]\)"),
    "mat-not-mat": ("H_0_1.mat", lambda data: b"x" * 200, "not a readable MATLAB file"),
    "mat-bomb": ("H_0_1.mat", lambda data: mat_bomb(), "more than the"),  # inflated 200 MB before its shape was seen
    "json-not-json": ("cameras.json", lambda data: b"{", "not valid JSON"),
    "json-long-integer": ("cameras.json", lambda data: b"{\"index\": " + b"9" * 5000 + b"}", "an integer of 5000 digits"),
    "json-too-large": ("cameras.json", lambda data: b"[" + b"0.5," * 50000 + b"0]", "larger than 73728 bytes"),
}


def zeros_png(shape, dtype=np.uint8):
    """A PNG of zeros of ``shape`` ``(H, W)`` or ``(H, W, 3)`` and ``dtype``."""
    buffer = io.BytesIO()
    Image.fromarray(np.zeros(shape, dtype)).save(buffer, format="PNG")
    return buffer.getvalue()


@pytest.mark.parametrize("case", list(FOLDER_FILES))
def test_a_malformed_sequence_file_is_a_value_error_naming_it_in_bounded_memory(exports, tmp_path, case):
    """Issue 34 item 3: a ``.mat`` without ``H`` (``KeyError``), a truncated PNG (``OSError``), a
    compressed ``.mat`` that inflated by 800 MB before its shape was checked."""
    name, change, named = FOLDER_FILES[case]
    out = copy_of(exports, "folders", tmp_path)
    replace_entry(out, "folders", name, change)
    message = read_with_bounded_memory(out)
    assert f"000000/{name}'" in message and re.search(named, message), message


SHARD_ENTRIES = {
    "npy-huge-shape": (lambda data: npy_header_declaring((3 * 10**9, 3, 3, 3)),
                       r"declares float64 of shape \(3000000000, 3, 3, 3\), expected \(2, 2, 3, 3\)"),  # MemoryError
    "npy-short": (lambda data: data[:-8], "holds 280 bytes of data, its header declares 288"),
    "npy-objects": (lambda data: np_save(np.array([None])), "declares object"),
    "npy-truncated-header": (lambda data: data[:20], "not a readable .npy file"),
}


def np_save(array):
    buffer = io.BytesIO()
    np.save(buffer, array, allow_pickle=True)
    return buffer.getvalue()


@pytest.mark.parametrize("case", list(SHARD_ENTRIES))
def test_a_malformed_shard_entry_is_a_value_error_naming_the_shard_and_entry(exports, tmp_path, case):
    change, named = SHARD_ENTRIES[case]
    out = copy_of(exports, "shards", tmp_path)
    replace_entry(out, "shards", "homographies.npy", change)
    message = read_with_bounded_memory(out)
    assert "shard-00000.tar'" in message and "000000.homographies.npy" in message, message
    assert re.search(named, message), message


@pytest.mark.parametrize("size", [10**15, -1])
def test_a_tar_member_declaring_1e15_or_negative_bytes_is_a_damaged_shard(exports, tmp_path, size):
    """Issue 34 item 3: a tar member declaring 1e15 bytes gave ``OSError`` (a seek past what the
    file system allows); a negative size read the rest of the shard, however large."""
    out = copy_of(exports, "shards", tmp_path)
    shard = out / "shard-00000.tar"
    data = shard.read_bytes()
    entries_end = -(-len(data.rstrip(b"\0")) // 512) * 512
    info = tarfile.TarInfo("000000.extra.png")
    info.size = max(size, 1)
    header = bytearray(info.tobuf(tarfile.GNU_FORMAT))  # 1e15: base-256, as GNU tar writes sizes over 8 GiB
    if size < 0:
        header[124:136] = b"\xff" * 12  # -1 in base-256
        header[148:156] = b" " * 8
        header[148:156] = b"%06o\0 " % sum(header)
    shard.write_bytes(data[:entries_end] + bytes(header) + bytes(512) + bytes(1024))
    message = read_with_bounded_memory(out, item=False)
    assert "shard-00000.tar': damaged shard" in message and "000000.extra.png" in message, message
