"""Hostile files in a folder of the SIDAR paper's sequences (``sidar_torch.io.paper``): each malformed
file is a ``ValueError`` naming it, read in bounded memory, and nothing blocks."""

import io
import os
import re
import struct
import threading
import time
import tracemalloc
import zlib

import numpy as np
import pytest
import torch
from PIL import Image

from sidar_torch import ExportedDataset
from sidar_torch.io import paper
from test_paper_layout import paper_sequence


def png(pixels):
    buffer = io.BytesIO()
    Image.fromarray(pixels).save(buffer, format="PNG")
    return buffer.getvalue()


def chunk(kind, body):
    """A PNG chunk of type ``kind`` holding ``body``, with its CRC."""
    return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))


def hostile_png(kind):
    """An RGBA PNG (the paper's kind, so the reader converts it) that Pillow fails on."""
    data = png(np.zeros((6, 8, 4), np.uint8))
    if kind == "apng-frame-after-idat":  # Pillow raises SyntaxError while decoding
        end = data.rindex(b"IEND") - 4
        frame = struct.pack(">IIIIIHHBB", 5, 8, 6, 0, 0, 1, 1, 0, 0)
        return data[:end] + chunk(b"fcTL", frame) + data[end:]
    if kind == "bomb-header":  # 20000 x 20000 pixels: Pillow's DecompressionBombError
        header = struct.pack(">II", 20000, 20000) + data[24:29]
        return data[:8] + chunk(b"IHDR", header) + data[33:]
    assert kind == "truncated"
    return data[:len(data) // 2]


@pytest.mark.parametrize("kind", ["apng-frame-after-idat", "bomb-header", "truncated"])
def test_a_papers_png_pillow_fails_on_is_a_value_error_naming_it(tmp_path, kind):
    paper_sequence(tmp_path / "seq01", np.random.default_rng(0), np.eye(3))
    view = tmp_path / "seq01" / "1.png"
    view.write_bytes(hostile_png(kind))
    with pytest.raises(ValueError, match=rf"{re.escape(str(view))}'"):
        ExportedDataset(tmp_path)[0]


def test_a_papers_png_of_many_pixels_is_refused_before_it_is_decoded(tmp_path):
    """3000 x 3000 RGBA zeros: 35 kB of file, 36 MB once decoded."""
    paper_sequence(tmp_path / "seq01", np.random.default_rng(0), np.eye(3))
    view = tmp_path / "seq01" / "1.png"
    view.write_bytes(png(np.zeros((3000, 3000, 4), np.uint8)))
    read = ExportedDataset(tmp_path)
    tracemalloc.start()
    try:
        with pytest.raises(ValueError, match=rf"{re.escape(str(view))}': its header says 3000 x 3000 pixels"):
            read[0]
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 8 * 2**20, peak


def test_a_homographies_npy_of_another_shape_is_a_value_error_naming_it(tmp_path):
    paper_sequence(tmp_path / "seq01", np.random.default_rng(0), np.eye(3))
    np.save(tmp_path / "seq01" / paper.HOMOGRAPHIES, np.zeros((3, 3, 3, 3)))
    with pytest.raises(ValueError, match=r"homographies.npy': its header declares float64 of shape \(3, 3, 3, 3\), "
                                         r"expected \(2, 2, 3, 3\)"):
        ExportedDataset(tmp_path)[0]


def test_a_fifo_swapped_in_for_gt_png_is_refused_without_blocking(tmp_path, monkeypatch):
    """``paper_folders`` saw a regular ``gt.png``; a FIFO took its place before ``paper_manifest``
    opened it. A writer thread stands by to unblock a reader that waits on the FIFO (and records it)."""
    folder = tmp_path / "seq01"
    paper_sequence(folder, np.random.default_rng(0), np.eye(3))
    (folder / paper.LABEL).unlink()
    os.mkfifo(folder / paper.LABEL)
    monkeypatch.setattr(paper, "paper_folders", lambda _: [folder])
    blocked, done = [], threading.Event()

    def unblock():
        while not done.wait(0.1):
            try:
                os.close(os.open(folder / paper.LABEL, os.O_WRONLY | os.O_NONBLOCK))  # ENXIO: no reader waits
            except OSError:
                continue
            blocked.append(time.monotonic())
            return

    writer = threading.Thread(target=unblock, daemon=True)
    writer.start()
    try:
        with pytest.raises(ValueError, match=rf"{re.escape(str(folder / paper.LABEL))}': not a regular file: expected a regular "
                                             r"file, got a FIFO"):
            paper.paper_manifest(tmp_path)
    finally:
        done.set()
        writer.join()
    assert not blocked


def corner_homography():
    """A valid homography in the paper's pixels with some perspective (det 1)."""
    H = np.array([[1.1, 0.05, 2.0], [0.02, 0.95, -1.0], [0.001, 0.002, 1.0]])
    return H / np.cbrt(np.linalg.det(H))


@pytest.mark.parametrize("scale", [1e-5, 1e300])
def test_a_homography_text_reads_the_same_at_any_scale(tmp_path, scale):
    """Issue 48: the check was ``|det H| >= 1e-12``, so a valid H scaled by 1e-5 was refused and
    ``1e308 * I`` passed it, to fail later with LinAlgError."""
    for name, H in (("one", corner_homography()), ("scaled", corner_homography() * scale)):
        (tmp_path / name).mkdir()
        paper_sequence(tmp_path / name / "seq01", np.random.default_rng(0), H)
    H = ExportedDataset(tmp_path / "one", geometry_dtype="float64")[0]["homographies"]
    scaled = ExportedDataset(tmp_path / "scaled", geometry_dtype="float64")[0]["homographies"]
    np.testing.assert_allclose(scaled.numpy(), H.numpy(), rtol=1e-13, atol=1e-13)


def test_1e308_times_the_identity_reads_as_the_identity(tmp_path):
    paper_sequence(tmp_path / "seq01", np.random.default_rng(0), 1e308 * np.eye(3))
    H = ExportedDataset(tmp_path, geometry_dtype="float64")[0]["homographies"].numpy()
    np.testing.assert_allclose(H, np.broadcast_to(np.eye(3), H.shape), atol=1e-15)


@pytest.mark.parametrize("H, reason", [
    (np.diag([1.0, 1.0, 0.0]), "condition number inf"),
    (np.diag([1.0, 1.0, 1e-13]), "condition number 1e\\+13"),
    (np.where(np.eye(3) > 0, np.nan, 0.0), "nan"),
    (np.zeros((3, 3)), r"got \[\[0.0, 0.0, 0.0\]"),
])
def test_a_singular_or_not_finite_homography_text_is_refused_naming_the_file_and_why(tmp_path, H, reason):
    paper_sequence(tmp_path / "seq01", np.random.default_rng(0), np.eye(3))
    np.savetxt(tmp_path / "seq01" / "H_0_1.mat", H)
    with pytest.raises(ValueError, match=rf"seq01/H_0_1.mat': expected an invertible homography .*{reason}"):
        ExportedDataset(tmp_path)[0]


@pytest.mark.parametrize("name", ["H_0_1.mat", "1-m.png", "1.png"])
def test_a_missing_file_of_a_papers_sequence_is_a_value_error_naming_it(tmp_path, name):
    """Issue 48: a missing ``H_0_1.mat`` or mask was ``FileNotFoundError``. (A missing view makes the
    sequence one of fewer views than the first, which is named when the folder is opened.)"""
    paper_sequence(tmp_path / "seq01", np.random.default_rng(0), np.eye(3))
    paper_sequence(tmp_path / "seq02", np.random.default_rng(1), np.eye(3))
    (tmp_path / "seq02" / name).unlink()
    with pytest.raises(ValueError, match=rf"seq02/{re.escape(name)}' does not exist|seq02': holds 1 views"):
        ExportedDataset(tmp_path)[1]


def test_the_papers_homographies_read_in_float64_when_asked(tmp_path):
    """Issue 48: the texts hold 17 digits, but a paper folder was read in float32 only (11.8 px off
    near the horizon of the paper's sequence 5)."""
    paper_sequence(tmp_path / "seq01", np.random.default_rng(0), corner_homography())
    exact = paper.kornia_from_paper(corner_homography(), (6, 8))
    wide = ExportedDataset(tmp_path, geometry_dtype="float64")
    assert wide.geometry_dtype == "float64" and ExportedDataset(tmp_path).geometry_dtype == "float32"
    H = wide[0]["homographies"]
    assert H.dtype == torch.float64 and wide[0]["K"].dtype == torch.float64
    np.testing.assert_allclose(H[0, 1].numpy(), exact, rtol=1e-14, atol=1e-15)
    assert ExportedDataset(tmp_path)[0]["homographies"].dtype == torch.float32
    with pytest.raises(ValueError, match=r"geometry_dtype: expected one of \['float32', 'float64'\] or None"):
        ExportedDataset(tmp_path, geometry_dtype=[])
