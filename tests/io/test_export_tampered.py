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


# --------------------------------------------------------------------------- issue 48: numbers, sizes, layouts


def numbers_edits():
    nan, inf = float("nan"), float("inf")
    K = [[30.0, 0.0, 15.5], [0.0, 30.0, 11.5], [0.0, 0.0, 1.0]]
    return {
        "K-zeros": ({"K": [[[0.0] * 3] * 3, K]}, r"field 'K': view 0: expected finite pinhole intrinsics"),
        "K-nan": ({"K": [K, [[nan] * 3] * 3]}, r"field 'K': view 1: expected finite pinhole intrinsics"),
        "K-inf": ({"K": [K, [[inf, 0.0, 15.5], [0.0, 30.0, 11.5], [0.0, 0.0, 1.0]]]}, "field 'K': view 1"),
        "R-not-a-rotation": ({"R": [[[2.0, 0, 0], [0, 1, 0], [0, 0, 1]]] * 2}, r"field 'R': view 0: expected a rotation"),
        "t-nan": ({"t": [[0.0, 0.0, 1.0], [nan, 0.0, 1.0]]}, r"field 't': view 1: expected finite numbers"),
        "error-nan": ({"homography_error": nan}, "'homography_error': expected a finite number >= 0"),
    }


@pytest.mark.parametrize("case", list(numbers_edits()))
@pytest.mark.parametrize("layout", ["folders", "shards"])
def test_cameras_json_of_numbers_no_camera_has_is_a_value_error_naming_the_field(exports, tmp_path, layout, case):
    """Issue 48: K of zeros, NaN or inf (and R, t, homography_error) were read as they were."""
    out = copy_of(exports, layout, tmp_path)
    edit, named = numbers_edits()[case]
    replace_entry(out, layout, "cameras.json", lambda data: json.dumps({**json.loads(data), **edit}).encode())
    message = read_with_bounded_memory(out)
    assert ("000000/cameras.json'" in message or "000000.cameras.json" in message) and re.search(named, message), message


@pytest.mark.parametrize("H, layout", [(np.full((3, 3), np.nan), "folders"), (np.diag([1.0, 1.0, 0.0]), "folders"),
                                       (np.full((3, 3), np.nan), "shards"), (np.full((3, 3), 1e300), "shards")])
def test_a_homography_file_of_nan_or_a_singular_matrix_is_a_value_error_naming_it(exports, tmp_path, H, layout):
    """Issue 48: ``H_i_j.mat`` of NaN was read as it was (evaluate then printed MACE nan)."""
    out = copy_of(exports, layout, tmp_path)
    if layout == "folders":
        replace_entry(out, layout, "H_0_1.mat", lambda data: mat_of(H=H))
        expected = "000000/H_0_1.mat': expected an invertible homography"
    else:
        def tampered(data):
            homographies = np.load(io.BytesIO(data))
            homographies[0, 1] = H
            return np_save(homographies)
        replace_entry(out, layout, "homographies.npy", tampered)
        expected = r"000000.homographies.npy: H\[0, 1\]: expected an invertible homography"
    assert re.search(expected, read_with_bounded_memory(out))


@pytest.fixture(scope="module")
def lens_export(tmp_path_factory):
    """One TINY sequence through division lenses, exported in the folder layout."""
    out = tmp_path_factory.mktemp("lens") / "folders"
    export_dataset(tiny_dataset(lens_model="division"), out, count=1, progress=False)
    return out


@pytest.mark.parametrize("lens, named", [
    ([1e300, 0, 0, 0, 0], r"a coefficient at the image's corner is .*, outside the bounds \[-0.5, 0.5\] of config "
                          r"field 'lens_lambda'"),
    ([float("nan"), 0, 0, 0, 0], "expected finite coefficients"),
    ([-0.1, 0.5, 0, 0, 0], "coefficient 1 is 0.5, expected 0: lens_model 'division' has no such coefficient"),
])
def test_a_lens_no_config_allows_is_a_value_error_naming_the_field(lens_export, tmp_path, lens, named):
    """Issue 48: lens coefficients of 1e300 or NaN were read as they were."""
    out = tmp_path / "folders"
    shutil.copytree(lens_export, out)
    path = out / "000000" / "cameras.json"
    cameras = json.loads(path.read_text())
    cameras["lens"][1] = lens
    path.write_text(json.dumps(cameras))
    message = read_with_bounded_memory(out)
    assert "000000/cameras.json'" in message and "field 'lens': view 1: " in message and re.search(named, message), message


@pytest.mark.parametrize("kind, size", [(tarfile.GNUTYPE_LONGNAME, 10**11), (tarfile.XHDTYPE, 4 * 2**30)])
def test_a_long_name_or_pax_header_claiming_gigabytes_is_a_damaged_shard_read_in_bounded_memory(
        exports, tmp_path, kind, size):
    """Issue 48: a GNU long name claiming 1e11 bytes was ``MemoryError`` naming no file; a pax header
    claiming 4 GiB allocated 4 GiB."""
    out = copy_of(exports, "shards", tmp_path)
    shard = out / "shard-00000.tar"
    data = shard.read_bytes()
    entries_end = -(-len(data.rstrip(b"\0")) // 512) * 512
    info = tarfile.TarInfo("././@LongLink")
    info.type, info.size = kind, size
    shard.write_bytes(data[:entries_end] + info.tobuf(tarfile.GNU_FORMAT) + b"x" * 512 + bytes(1024))
    message = read_with_bounded_memory(out, item=False)
    assert "shard-00000.tar': damaged shard" in message, message


def test_a_manifest_claiming_a_large_image_is_read_in_the_files_memory(exports, tmp_path):
    """Issue 48: every read reserved the most bytes the manifest allows (385 MiB a file for 5792 x 5792,
    192 MiB for 4000 x 4000)."""
    out = copy_of(exports, "folders", tmp_path)
    manifest = json.loads((out / "export.json").read_text())
    manifest["config"]["image_size"] = [4000, 4000]
    (out / "export.json").write_text(json.dumps(manifest))
    replace_entry(out, "folders", "cameras.json",
                  lambda data: json.dumps({**json.loads(data), "image_size": [4000, 4000]}).encode())
    message = read_with_bounded_memory(out)
    assert "000000/0.png': not a PNG of 4000 x 4000 pixels" in message, message


@pytest.mark.parametrize("layout, recorded", [("folders", ("shards", 1)), ("shards", ("folders", None))])
def test_a_manifest_naming_another_layout_than_the_files_is_a_value_error(exports, tmp_path, layout, recorded):
    """Issue 48: ``"layout": "shards"`` on a folder export read as an empty set, with no error."""
    out = copy_of(exports, layout, tmp_path)
    manifest = json.loads((out / "export.json").read_text())
    manifest["layout"], manifest["shard_size"] = recorded
    (out / "export.json").write_text(json.dumps(manifest))
    message = read_with_bounded_memory(out, item=False)
    assert re.search(rf"export.json': records layout '{recorded[0]}', but .* holds no sequence of that layout "
                     r"\(found 3: '(000000|config.yaml)', ", message), message


@pytest.mark.parametrize("field", ["geometry_dtype", "lens_model"])
def test_a_config_name_of_another_type_is_a_value_error_naming_the_field(exports, tmp_path, field):
    """Issue 48: ``"geometry_dtype": []`` gave ``TypeError`` (a list is no key of a dict)."""
    out = copy_of(exports, "folders", tmp_path)
    manifest = json.loads((out / "export.json").read_text())
    manifest["config"][field] = []
    (out / "export.json").write_text(json.dumps(manifest))
    assert f"field 'config.{field}': expected one of" in read_with_bounded_memory(out, item=False)


def shard_with(out, keep, extra):
    """Rewrite shard 0 of ``out`` with its entries whose name ``keep`` accepts, then empty entries named ``extra``."""
    shard = out / "shard-00000.tar"
    with tarfile.open(shard) as tar:
        kept = [(m, tar.extractfile(m).read()) for m in tar if keep(m.name)]
    with tarfile.open(shard, "w") as tar:
        for member, data in kept:
            tar.addfile(member, io.BytesIO(data))
        for name in extra:
            tar.addfile(tarfile.TarInfo(name), io.BytesIO(b""))


def test_a_shard_of_many_empty_entries_stops_at_the_most_a_sequence_holds(exports, tmp_path):
    """Issue 48: 200k empty entries of a sequence took 94 s to read, then an error listing every name."""
    from sidar_torch.io.shards import MAX_SEQUENCE_ENTRIES

    out = copy_of(exports, "shards", tmp_path)
    shard_with(out, lambda name: True, [f"000000.x{i}.png" for i in range(3 * MAX_SEQUENCE_ENTRIES)])
    message = read_with_bounded_memory(out, item=False)
    assert f"sequence 000000 has more than {MAX_SEQUENCE_ENTRIES} entries" in message and len(message) < 400, message
    out = copy_of(exports, "shards", tmp_path / "foreign")
    shard_with(out, lambda name: True, ["000007.gt.png"])  # shard 0 of 1 sequence holds sequence 0 only
    assert "entry '000007.gt.png' is of sequence 7, not one of the shard's [0, 1)" in read_with_bounded_memory(out, False)


def test_a_missing_shard_entry_names_the_shard_and_a_few_of_the_entries(exports, tmp_path):
    out = copy_of(exports, "shards", tmp_path)
    shard_with(out, lambda name: name != "000000.cameras.json", [f"000000.x{i}.png" for i in range(1000)])
    message = read_with_bounded_memory(out)
    assert re.search(r"shard-00000.tar': the sequence has no entry 'cameras.json' \(its entries, 10\d\d: '0-m.png', "
                     r"'0.png', .*, \.\.\.\)", message) and len(message) < 400, message
