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
