"""Tests for sidar_torch.paintings (decode and sources)."""

from __future__ import annotations

import json
import os
import pickle
import struct
import subprocess
import sys
import warnings
import zlib
from pathlib import Path

import numpy as np
import pytest
import torch
from PIL import Image
from PIL import JpegImagePlugin

from conftest import SMALL, small_config
from sidar_torch import SidarDataset
from sidar_torch.paintings import decode
from sidar_torch.paintings import (
    BadImageWarning,
    DatasetPaintings,
    ImageFiles,
    ImageTooLargeError,
    ImageList,
    PaintingSource,
    ProceduralPaintings,
    TensorPaintings,
    fit_painting,
    make_source,
)

ODD_SIZES = [(131, 257), (40, 320), (320, 40)]
RED, GREEN, BLUE = (255, 0, 0), (0, 255, 0), (0, 0, 255)


# --------------------------------------------------------------------------- helpers


def _random_rgb(height: int, width: int, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, 256, (height, width, 3), dtype=np.uint8)


def _save(image: Image.Image, path: Path, **kwargs) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    image.save(path, **kwargs)
    return path


def _solid(path: Path, color: tuple[int, int, int], size: tuple[int, int] = (24, 16), **kwargs) -> Path:
    return _save(Image.new("RGB", size, color), path, **kwargs)


def _thirds(width: int = 360, height: int = 120) -> Image.Image:
    """Left third red, middle third green, right third blue."""
    image = Image.new("RGB", (width, height), RED)
    image.paste(GREEN, (width // 3, 0, 2 * width // 3, height))
    image.paste(BLUE, (2 * width // 3, 0, width, height))
    return image


def _single_pixel_source(image: Image.Image, tmp_path: Path, name: str = "img.png", **save_kwargs) -> np.ndarray:
    """Save ``image``, read it back through make_source at its own size (no resampling)."""
    path = _save(image, tmp_path / name, **save_kwargs)
    return make_source(path).painting(0, (image.height, image.width))


def _png16_rgb(path: Path, values: np.ndarray) -> Path:
    """Write ``(h, w, 3)`` ``uint16`` ``values`` as a 16-bit RGB PNG (Pillow cannot write one)."""

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    height, width, _ = values.shape
    rows = b"".join(b"\0" + row.astype(">u2").tobytes() for row in values)  # filter type 0 per row
    header = struct.pack(">IIBBBBB", width, height, 16, 2, 0, 0, 0)  # 16 bits, colour type 2 (RGB)
    chunks = chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(rows)) + chunk(b"IEND", b"")
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunks)
    return path


def _lock(path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Take away read permission on ``path``.

    Root reads files whatever their mode, so where ``chmod`` does not stop this
    process, Pillow's ``Image.open`` is made to fail for ``path`` as the OS would.
    """
    path.chmod(0)
    if os.access(path, os.R_OK):
        real_open = Image.open

        def refusing_open(fp, *args, **kwargs):
            if os.fspath(fp) == os.fspath(path):
                raise PermissionError(13, "Permission denied", os.fspath(fp))
            return real_open(fp, *args, **kwargs)

        monkeypatch.setattr(Image, "open", refusing_open)


BAD_FILE_KINDS = ["not_an_image", "truncated_png", "truncated_jpg", "corrupt_png", "no_permission", "deleted"]


def _three_files(folder: Path, bad_kind: str) -> tuple[list[Path], list[np.ndarray]]:
    """Files ``a.png``, ``b``, ``c.png`` of 64 x 64 random pixels; ``b`` is a JPEG for ``truncated_jpg``.

    Returns the paths and the pixels of ``a`` and ``c``.
    """
    pixels = [_random_rgb(64, 64, seed) for seed in range(3)]
    names = ["a.png", "b.jpg" if bad_kind == "truncated_jpg" else "b.png", "c.png"]
    paths = [_save(Image.fromarray(p), folder / name) for p, name in zip(pixels, names)]
    return paths, [pixels[0], pixels[2]]


def _spoil(path: Path, kind: str, monkeypatch: pytest.MonkeyPatch) -> tuple[type[Exception], str]:
    """Make the image file ``path`` unreadable in the way ``kind`` (one of :data:`BAD_FILE_KINDS`) says.

    Returns the exception reading it raises with ``on_bad_image="raise"`` and words of
    its message that name the problem.
    """
    data = path.read_bytes()
    middle = len(data) // 2
    if kind == "not_an_image":
        path.write_text("hello, not an image")
        return ValueError, "cannot identify image file"
    if kind in ("truncated_png", "truncated_jpg"):
        path.write_bytes(data[:middle])
        return ValueError, "truncated"
    if kind == "corrupt_png":
        path.write_bytes(data[:middle] + bytes([data[middle] ^ 0xFF]) + data[middle + 1 :])  # one flipped byte
        return ValueError, "broken data stream"
    if kind == "no_permission":
        _lock(path, monkeypatch)
        return PermissionError, "Permission denied"
    assert kind == "deleted"
    path.unlink()
    return FileNotFoundError, "No such file"


class PairDataset:
    """A torchvision-style dataset of (image tensor, label) pairs."""

    def __init__(self, images: torch.Tensor) -> None:
        self.images = images

    def __len__(self) -> int:
        return len(self.images)

    def __getitem__(self, index: int) -> tuple[torch.Tensor, int]:
        return self.images[index], index


class PilDataset:
    def __len__(self) -> int:
        return 2

    def __getitem__(self, index: int) -> Image.Image:
        return Image.new("RGB", (30 + index, 20), (10 * index, 50, 90))


class BadItemDataset:
    def __len__(self) -> int:
        return 1

    def __getitem__(self, index: int) -> str:
        return "not an image"


class FlakyDataset:
    """Four grey tensors, but item 1 fails to load (as a broken file in an ImageFolder would) and item 2 is a string."""

    def __len__(self) -> int:
        return 4

    def __getitem__(self, index: int) -> tuple[torch.Tensor | str, int]:
        if index == 1:
            raise OSError("cannot identify image file 'broken.jpg'")
        return ("not an image" if index == 2 else torch.full((3, 4, 4), index / 10)), index


def _build(kind: str, tmp_path: Path) -> PaintingSource:
    """One source of each accepted kind, each with at least two paintings."""
    if kind == "none":
        return make_source(None)
    if kind in ("folder", "file", "path_list"):
        paths = [
            _save(Image.fromarray(_random_rgb(50, 70, seed)), tmp_path / f"img{seed}.png") for seed in range(2)
        ]
        return make_source({"folder": tmp_path, "file": str(paths[0]), "path_list": paths}[kind])
    if kind == "tensor4d":
        return make_source(torch.rand(2, 3, 33, 47))
    if kind == "tensor3d_uint8":
        return make_source(torch.from_numpy(_random_rgb(33, 47)).permute(2, 0, 1))
    if kind == "mixed_list":
        return make_source([torch.rand(3, 20, 30), Image.fromarray(_random_rgb(41, 17)), Image.new("L", (9, 5), 3)])
    if kind == "dataset":
        return make_source(PairDataset(torch.rand(3, 3, 25, 35)))
    raise AssertionError(kind)


SOURCE_KINDS = ["none", "folder", "file", "path_list", "tensor4d", "tensor3d_uint8", "mixed_list", "dataset"]


# --------------------------------------------------------------------------- every source kind


@pytest.mark.parametrize("kind", SOURCE_KINDS)
@pytest.mark.parametrize("size", ODD_SIZES)
def test_every_source_gives_uint8_rgb_of_requested_size(kind, size, tmp_path):
    source = _build(kind, tmp_path)
    for index in range(3):
        out = source.painting(index, size)
        assert out.shape == (*size, 3)
        assert out.dtype == np.uint8
        assert out.flags.c_contiguous


@pytest.mark.parametrize("kind", SOURCE_KINDS)
def test_index_is_taken_modulo_length_and_negative_index_fails(kind, tmp_path):
    source = _build(kind, tmp_path)
    np.testing.assert_array_equal(source.painting(len(source) + 1, (20, 30)), source.painting(1, (20, 30)))
    with pytest.raises(ValueError, match="index"):
        source.painting(-1, (20, 30))


@pytest.mark.parametrize("kind", SOURCE_KINDS)
def test_pickle_round_trip_gives_same_paintings(kind, tmp_path):
    source = _build(kind, tmp_path)
    clone = pickle.loads(pickle.dumps(source))
    assert type(clone) is type(source) and len(clone) == len(source)
    for index in range(2):
        np.testing.assert_array_equal(clone.painting(index, (31, 45)), source.painting(index, (31, 45)))


@pytest.mark.parametrize("size", [(0, 5), (5, -1), (5,), (2.5, 3), "ab", None, (True, 4)])
def test_invalid_size_raises(size):
    with pytest.raises(ValueError, match="size"):
        ProceduralPaintings().painting(0, size)
    with pytest.raises(ValueError, match="size"):
        TensorPaintings(torch.rand(3, 4, 4)).painting(0, size)


def test_source_kinds_map_to_classes(tmp_path):
    _solid(tmp_path / "a.png", RED)
    assert isinstance(make_source(None), ProceduralPaintings)
    assert isinstance(make_source(tmp_path), ImageFiles)
    assert isinstance(make_source(str(tmp_path / "a.png")), ImageFiles)
    assert isinstance(make_source(torch.rand(3, 4, 4)), TensorPaintings)
    assert isinstance(make_source([torch.rand(3, 4, 4)]), ImageList)
    assert isinstance(make_source(PilDataset()), DatasetPaintings)
    existing = TensorPaintings(torch.rand(3, 4, 4))
    assert make_source(existing) is existing


@pytest.mark.parametrize(
    "bad", [42, 3.5, b"bytes", {"a": 1}, [1, 2], [torch.rand(3, 4, 4), "x.png"]]
)  # a NumPy array is a source since issue 34 (tests/paintings/test_numpy_sources.py)
def test_unsupported_source_raises_type_error_naming_source(bad):
    with pytest.raises(TypeError, match="source") as info:
        make_source(bad)
    assert "PIL" in str(info.value) and "Tensor" in str(info.value)


@pytest.mark.parametrize("crop", ["middle", "", None, "CENTER"])
def test_invalid_crop_raises(crop, tmp_path):
    with pytest.raises(ValueError, match="crop"):
        make_source(None, crop=crop)
    with pytest.raises(ValueError, match="crop"):
        ImageFiles([tmp_path / "x.png"], crop=crop)


@pytest.mark.parametrize("value", ["ignore", "", None, "SKIP"])
def test_invalid_on_bad_image_raises_naming_it(value, tmp_path):
    with pytest.raises(ValueError, match=r"on_bad_image must be one of \('raise', 'skip'\)"):
        make_source(None, on_bad_image=value)
    with pytest.raises(ValueError, match="on_bad_image"):
        ImageFiles([tmp_path / "x.png"], on_bad_image=value)
    with pytest.raises(ValueError, match="on_bad_image"):
        DatasetPaintings(PilDataset(), on_bad_image=value)


# --------------------------------------------------------------------------- procedural paintings


def test_procedural_is_deterministic():
    a = ProceduralPaintings().painting(7, (96, 128))
    b = ProceduralPaintings().painting(7, (96, 128))
    np.testing.assert_array_equal(a, b)


def test_procedural_does_not_use_global_random_state():
    np.random.seed(1)
    torch.manual_seed(1)
    a = ProceduralPaintings().painting(3, (64, 64))
    np.random.seed(2)
    torch.manual_seed(2)
    np.testing.assert_array_equal(a, ProceduralPaintings().painting(3, (64, 64)))


def test_procedural_indices_differ():
    paintings = [ProceduralPaintings().painting(i, (96, 128)).astype(np.int16) for i in range(5)]
    for i in range(5):
        for j in range(i + 1, 5):
            assert np.abs(paintings[i] - paintings[j]).mean() > 10


@pytest.mark.parametrize("size", [(768, 1024), (384, 512), (131, 257), (40, 320)])
def test_procedural_has_texture_everywhere(size):
    for index in range(4):
        out = ProceduralPaintings().painting(index, size).astype(np.float64)
        h, w = (size[0] // 8) * 8, (size[1] // 8) * 8
        blocks = out[:h, :w].reshape(h // 8, 8, w // 8, 8, 3)
        block_std = blocks.std(axis=(1, 3)).max(axis=-1)  # per 8x8 block, most textured channel
        assert (block_std < 1).mean() < 0.01
        assert np.median(block_std) > 4
        assert out.std() > 20  # colourful, not just noise around one grey


def test_procedural_same_index_at_two_sizes_looks_alike():
    source = ProceduralPaintings()
    big = Image.fromarray(source.painting(5, (384, 512))).resize((256, 192), Image.Resampling.LANCZOS)
    big = np.asarray(big, dtype=np.int16)
    same = np.abs(big - source.painting(5, (192, 256)).astype(np.int16)).mean()
    other = np.abs(big - source.painting(6, (192, 256)).astype(np.int16)).mean()
    assert same < 12
    assert same < other / 3


def test_procedural_count_and_validation():
    assert len(ProceduralPaintings()) == 100_000
    assert len(ProceduralPaintings(3)) == 3
    small = ProceduralPaintings(3)
    np.testing.assert_array_equal(small.painting(4, (8, 8)), small.painting(1, (8, 8)))
    assert ProceduralPaintings(1).painting(0, (1, 1)).shape == (1, 1, 3)
    with pytest.raises(ValueError, match="count"):
        ProceduralPaintings(0)


# --------------------------------------------------------------------------- crop and resample


def test_image_already_at_size_is_bit_identical(tmp_path):
    pixels = _random_rgb(37, 53)
    path = _save(Image.fromarray(pixels), tmp_path / "exact.png")
    for crop in ("center", "none"):
        np.testing.assert_array_equal(make_source(path, crop=crop).painting(0, (37, 53)), pixels)
    np.testing.assert_array_equal(make_source(torch.from_numpy(pixels).permute(2, 0, 1)).painting(0, (37, 53)), pixels)
    np.testing.assert_array_equal(make_source([Image.fromarray(pixels)]).painting(0, (37, 53)), pixels)


def test_center_crop_keeps_only_the_middle(tmp_path):
    path = _save(_thirds(), tmp_path / "thirds.png")
    out = make_source(path).painting(0, (40, 40)).astype(np.int16)  # box = middle third, 3x downscale
    np.testing.assert_allclose(out[:, 1:-1].reshape(-1, 3), np.broadcast_to(GREEN, (40 * 38, 3)), atol=3)
    assert (out[..., 1] > 200).all()


def test_crop_none_stretches_the_whole_image(tmp_path):
    path = _save(_thirds(), tmp_path / "thirds.png")
    out = make_source(path, crop="none").painting(0, (30, 30))
    assert tuple(out[15, 2]) == RED and tuple(out[15, 15]) == GREEN and tuple(out[15, -3]) == BLUE


def test_center_crop_box_is_fractional_and_centred():
    image = Image.fromarray(_random_rgb(60, 101))
    # scale = min(101 / 37, 60 / 50) = 1.2 -> box 44.4 x 60 starting at x = 28.3
    expected = image.resize((37, 50), Image.Resampling.LANCZOS, box=(28.3, 0.0, 72.7, 60.0))
    out = fit_painting(image, (50, 37))
    np.testing.assert_array_equal(out, np.asarray(expected))


def test_center_crop_of_mirror_symmetric_image_is_symmetric():
    half = _random_rgb(60, 50)
    image = Image.fromarray(np.concatenate([half, half[:, :1], half[:, ::-1]], axis=1))  # width 101
    out = fit_painting(image, (50, 37)).astype(np.int16)
    assert np.abs(out - out[:, ::-1]).max() <= 1


def test_exif_orientation_is_applied(tmp_path):
    image = Image.new("RGB", (40, 20), RED)
    image.paste(BLUE, (20, 0, 40, 20))
    exif = Image.Exif()
    exif[0x0112] = 6  # rotate 90 degrees clockwise for display: the left edge goes to the top
    path = _save(image, tmp_path / "rotated.png", exif=exif)
    out = make_source(path).painting(0, (40, 20))  # displayed size: no resampling
    assert tuple(out[5, 10]) == RED and tuple(out[35, 10]) == BLUE


# --------------------------------------------------------------------------- colour modes


def test_palette_with_transparency_is_composited_over_black(tmp_path):
    image = Image.new("P", (2, 1))
    image.putpalette([255, 0, 0, 0, 255, 0])
    image.putpixel((0, 0), 0)
    image.putpixel((1, 0), 1)
    out = _single_pixel_source(image, tmp_path, transparency=0)
    assert out[0].tolist() == [[0, 0, 0], [0, 255, 0]]


def test_plain_palette_and_grey(tmp_path):
    image = Image.new("P", (1, 1))
    image.putpalette([10, 20, 30])
    assert _single_pixel_source(image, tmp_path, "p.gif")[0, 0].tolist() == [10, 20, 30]
    assert _single_pixel_source(Image.new("L", (1, 1), 77), tmp_path, "l.png")[0, 0].tolist() == [77, 77, 77]


def test_la_and_rgba_are_composited_over_black(tmp_path):
    assert _single_pixel_source(Image.new("LA", (1, 1), (200, 128)), tmp_path, "la.png")[0, 0].tolist() == [100] * 3
    rgba = Image.new("RGBA", (1, 1), (255, 100, 0, 51))
    assert _single_pixel_source(rgba, tmp_path, "rgba.png")[0, 0].tolist() == [51, 20, 0]
    assert ImageList([rgba]).painting(0, (1, 1))[0, 0].tolist() == [51, 20, 0]


def test_cmyk_jpeg(tmp_path):
    out = _single_pixel_source(Image.new("CMYK", (16, 16), (0, 255, 255, 0)), tmp_path, "cmyk.jpg")
    assert (np.abs(out.astype(int) - RED) <= 8).all()


def test_16_bit_rgb_png_keeps_the_high_byte(tmp_path):
    values = np.array([[[0, 257, 65535], [32768, 1000, 65280]]], dtype=np.uint16)
    out = make_source(_png16_rgb(tmp_path / "deep_rgb.png", values)).painting(0, (1, 2))
    assert out.tolist() == [[[0, 1, 255], [128, 3, 255]]]  # v >> 8, as Pillow opens it


def test_16_bit_png_is_scaled_not_clipped(tmp_path):
    image = Image.fromarray(np.array([[0, 257, 32768, 65535]], dtype=np.uint16))
    out = _single_pixel_source(image, tmp_path, "deep.png")
    assert out[0, :, 0].tolist() == [0, 1, 128, 255]
    assert (out == out[..., :1]).all()


def test_32_bit_int_image_is_taken_as_16_bit():
    image = Image.fromarray(np.array([[-5, 32768, 65535, 70000]], dtype=np.int32))
    assert image.mode == "I"
    assert ImageList([image]).painting(0, (1, 4))[0, :, 0].tolist() == [0, 128, 255, 255]


def test_float_image_in_unit_range_is_scaled(tmp_path):
    image = Image.fromarray(np.array([[0.0, 0.25, 1.0]], dtype=np.float32))
    assert _single_pixel_source(image, tmp_path, "f.tif")[0, :, 0].tolist() == [0, 64, 255]


def test_float_image_beyond_unit_range_is_taken_as_0_255():
    image = Image.fromarray(np.array([[0.0, 100.0, 300.0, np.nan]], dtype=np.float32))
    assert ImageList([image]).painting(0, (1, 4))[0, :, 0].tolist() == [0, 100, 255, 0]


def test_one_pixel_image_is_upscaled(tmp_path):
    out = make_source(_solid(tmp_path / "dot.png", (9, 99, 199), size=(1, 1))).painting(0, (131, 257))
    assert (out == (9, 99, 199)).all()


# --------------------------------------------------------------------------- files and folders


@pytest.mark.parametrize("kind", BAD_FILE_KINDS)
def test_bad_file_raises_naming_file_and_problem(kind, tmp_path, monkeypatch):
    paths, _ = _three_files(tmp_path, kind)
    source = make_source(tmp_path)  # default on_bad_image="raise"; files are listed, not read
    error, problem = _spoil(paths[1], kind, monkeypatch)
    with pytest.raises(error, match=problem) as info:
        source.painting(1, (16, 16))
    assert str(paths[1]) in str(info.value)
    if error is ValueError:
        assert "cannot decode image file" in str(info.value)
    assert source.bad_images == {}


@pytest.mark.parametrize("kind", BAD_FILE_KINDS)
def test_bad_file_is_skipped_with_one_warning_and_counted(kind, tmp_path, monkeypatch):
    paths, (first, last) = _three_files(tmp_path, kind)
    source = make_source(tmp_path, on_bad_image="skip")
    _, problem = _spoil(paths[1], kind, monkeypatch)
    with pytest.warns(BadImageWarning) as record:
        out = source.painting(1, (64, 64))
    np.testing.assert_array_equal(out, last)  # the next readable file
    assert len(record) == 1
    assert str(paths[1]) in str(record[0].message) and problem in str(record[0].message)
    assert list(source.bad_images) == [str(paths[1])] and problem in source.bad_images[str(paths[1])]
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # one warning per file: asking again is silent
        np.testing.assert_array_equal(source.painting(1, (64, 64)), last)
        np.testing.assert_array_equal(source.painting(0, (64, 64)), first)
    assert len(source.bad_images) == 1


def test_skip_takes_next_readable_image_wrapping_around_in_any_order(tmp_path):
    pixels = [_random_rgb(8, 8, seed) for seed in range(4)]
    paths = [_save(Image.fromarray(p), tmp_path / f"{name}.png") for p, name in zip(pixels, "abcd")]
    for bad in (paths[1], paths[3]):
        bad.write_text("not an image")
    expected = {0: pixels[0], 1: pixels[2], 2: pixels[2], 3: pixels[0], 5: pixels[2], 7: pixels[0]}
    for order, warned in ((sorted(expected), 2), (sorted(expected, reverse=True), 0)):
        source = make_source(tmp_path, on_bad_image="skip")
        with warnings.catch_warnings(record=True) as record:  # the second source is silent: warned already
            warnings.simplefilter("always")
            got = {index: source.painting(index, (8, 8)) for index in order}
        assert len(record) == warned
        for index, painting in expected.items():
            np.testing.assert_array_equal(got[index], painting)
        assert sorted(source.bad_images) == [str(paths[1]), str(paths[3])]
    fresh = pickle.loads(pickle.dumps(make_source(tmp_path, on_bad_image="skip")))  # as a new worker gets it
    np.testing.assert_array_equal(fresh.painting(3, (8, 8)), pixels[0])
    assert sorted(fresh.bad_images) == [str(paths[3])]


def test_skip_with_no_readable_image_raises_instead_of_looping(tmp_path):
    for name in ("a.png", "b.jpg"):
        (tmp_path / name).write_text("not an image")
    source = make_source(tmp_path, on_bad_image="skip")
    with pytest.warns(BadImageWarning) as record, pytest.raises(ValueError, match="none of the 2 images") as info:
        source.painting(1, (8, 8))
    assert len(record) == 2 and str(tmp_path / "b.jpg") in str(info.value) and "cannot identify" in str(info.value)
    with warnings.catch_warnings(), pytest.raises(ValueError, match="none of the 2 images") as info:
        warnings.simplefilter("error")  # known bad files are not read again
        source.painting(0, (8, 8))
    assert str(tmp_path / "a.png") in str(info.value)


def test_dataset_item_that_fails_raises_or_is_skipped():
    strict = make_source(FlakyDataset())
    with pytest.raises(OSError, match="broken.jpg"):
        strict.painting(1, (4, 4))
    with pytest.raises(TypeError, match="painting item 2 .* got str"):
        strict.painting(2, (4, 4))
    lenient = make_source(FlakyDataset(), on_bad_image="skip")
    with pytest.warns(BadImageWarning) as record:
        assert (lenient.painting(1, (4, 4)) == 76).all()  # item 3: round(0.3 * 255)
    messages = [str(warning.message) for warning in record]
    assert "dataset item 1" in messages[0] and "OSError" in messages[0] and "broken.jpg" in messages[0]
    assert "dataset item 2" in messages[1] and "TypeError" in messages[1]
    assert sorted(lenient.bad_images) == ["dataset item 1", "dataset item 2"]


def test_sidar_dataset_takes_on_bad_image_from_its_config(tmp_path):
    _solid(tmp_path / "a.png", RED)
    (tmp_path / "b.png").write_text("not an image")
    strict = SidarDataset(tmp_path, config=small_config())
    with pytest.raises(ValueError, match="b.png"):
        strict.source.painting(1, SMALL)
    lenient = SidarDataset(tmp_path, config=small_config(on_bad_image="skip"))
    with pytest.warns(BadImageWarning, match="b.png"):
        assert (lenient.source.painting(1, SMALL) == RED).all()


@pytest.mark.parametrize("on_bad_image", ["raise", "skip"])
def test_nonexistent_path_raises_file_not_found(on_bad_image, tmp_path):
    missing = tmp_path / "nope"
    with pytest.raises(FileNotFoundError, match="nope"):
        make_source(missing, on_bad_image=on_bad_image)
    _solid(tmp_path / "ok.png", RED)
    with pytest.raises(FileNotFoundError, match="nope"):
        make_source([tmp_path / "ok.png", missing], on_bad_image=on_bad_image)


def test_folder_in_path_list_is_rejected(tmp_path):
    (tmp_path / "sub").mkdir()
    with pytest.raises(IsADirectoryError, match="sub"):
        make_source([tmp_path / "sub"])


@pytest.mark.parametrize("contents", ["nothing", "no_images"])
@pytest.mark.parametrize("on_bad_image", ["raise", "skip"])
def test_folder_without_images_raises_value_error(contents, on_bad_image, tmp_path):
    if contents == "no_images":
        (tmp_path / "nested" / "deeper").mkdir(parents=True)
        (tmp_path / "nested" / "readme.txt").write_text("no images here")
    with pytest.raises(ValueError, match="no image files") as info:
        make_source(tmp_path, on_bad_image=on_bad_image)
    assert str(tmp_path) in str(info.value)


@pytest.mark.parametrize("kind", ["empty_list", "empty_tuple", "empty_tensor", "empty_dataset", "empty_files"])
def test_empty_inputs_raise_value_error(kind):
    with pytest.raises(ValueError, match="empty"):
        if kind == "empty_list":
            make_source([])
        elif kind == "empty_tuple":
            make_source(())
        elif kind == "empty_tensor":
            make_source(torch.rand(0, 3, 4, 4))
        elif kind == "empty_dataset":
            make_source(PairDataset(torch.rand(0, 3, 4, 4)))
        else:
            ImageFiles([])


def test_folder_is_scanned_recursively_in_sorted_order(tmp_path):
    colors = {
        "a/b/c.jpg": (250, 0, 0),
        "a/z.PNG": (0, 250, 0),
        "b.gif": (0, 0, 250),
        "c.JPEG": (250, 250, 0),
        "d.bmp": (0, 250, 250),
        "e.webp": (250, 0, 250),
        "f/g.TIF": (120, 60, 30),
    }
    for relative, color in reversed(colors.items()):
        _solid(tmp_path / relative, color, **({"lossless": True} if relative.endswith("webp") else {}))
    (tmp_path / "skip.txt").write_text("not an image")
    (tmp_path / "a" / "b" / "skip.json").write_text("{}")
    source = make_source(tmp_path)
    assert [Path(p).relative_to(tmp_path).as_posix() for p in source.paths] == list(colors)
    for index, color in enumerate(colors.values()):
        assert np.abs(source.painting(index, (8, 8)).astype(int) - color).max() <= 3


@pytest.mark.parametrize("on_bad_image", ["raise", "skip"])
def test_unreadable_folder_raises_permission_error_naming_it(on_bad_image, tmp_path, monkeypatch):
    _solid(tmp_path / "ok.png", RED)
    locked = tmp_path / "locked"
    locked.mkdir()
    real_scandir = os.scandir

    def scandir(path="."):
        if os.fspath(path) == os.fspath(locked):
            raise PermissionError(13, "Permission denied", os.fspath(path))
        return real_scandir(path)

    monkeypatch.setattr(os, "scandir", scandir)
    with pytest.raises(PermissionError, match="locked"):
        make_source(tmp_path, on_bad_image=on_bad_image)


def test_files_are_opened_lazily(tmp_path, monkeypatch):
    paths = [_solid(tmp_path / f"{i}.png", (i, i, i)) for i in range(3)]
    opened = []
    real_open = Image.open

    def spy(fp, *args, **kwargs):
        opened.append(os.fspath(fp))
        return real_open(fp, *args, **kwargs)

    monkeypatch.setattr(Image, "open", spy)
    source = make_source(tmp_path)
    assert opened == []
    source.painting(1, (4, 4))
    assert opened == [str(paths[1])]


def test_a_large_jpeg_is_decoded_reduced_never_below_the_output_size(tmp_path, monkeypatch):
    path = _save(_thirds(720, 240), tmp_path / "huge.jpg", quality=95)
    drafts = []
    real_draft = JpegImagePlugin.JpegImageFile.draft

    def spy(self, mode, size):
        drafts.append(size)
        return real_draft(self, mode, size)

    monkeypatch.setattr(JpegImagePlugin.JpegImageFile, "draft", spy)
    monkeypatch.setattr(decode, "JPEG_DRAFT_PIXELS", 1000)  # 720 * 240 is "large"
    out = make_source(path).painting(0, (30, 30))
    assert drafts == [(30, 30)]
    assert (np.abs(out[:, 3:-3].astype(int) - GREEN) <= 12).all()


def test_an_image_above_the_pixel_budget_raises_naming_it_and_its_size_or_is_skipped(tmp_path):
    # issue 25 item 1: the budget is checked from the header, for every format, before decoding.
    small = _solid(tmp_path / "a.png", RED, size=(10, 10))
    for name in ("b.png", "b.jpg", "b.bmp", "b.tif", "b.webp", "b.gif"):
        big = _solid(tmp_path / name, BLUE, size=(11, 10))  # 110 pixels, one more than the budget
        strict = make_source([small, big], max_pixels=100)
        assert (strict.painting(0, (4, 4)) == RED).all()
        with pytest.raises(ImageTooLargeError, match=r"is 10 x 11 \(H x W\) = 110 pixels, more than "
                                                     r"max_image_pixels=100") as info:
            strict.painting(1, (4, 4))
        assert str(big) in str(info.value)
        lenient = make_source([small, big], on_bad_image="skip", max_pixels=100)
        with pytest.warns(BadImageWarning, match="110 pixels"):
            assert (lenient.painting(1, (4, 4)) == RED).all()
        assert list(lenient.bad_images) == [str(big)]
        at_budget = make_source(big, max_pixels=110).painting(0, (4, 4))  # decoded (JPEG, WebP: lossy)
        assert (np.abs(at_budget.astype(int) - BLUE) <= 8).all(), name


def test_the_dataset_takes_the_pixel_budget_from_its_config(tmp_path):
    big = _solid(tmp_path / "b.png", BLUE, size=(20, 20))
    with pytest.raises(ValueError, match=r"config field 'max_image_pixels': expected 1 <= value <= "):
        small_config(max_image_pixels=0)
    assert SidarDataset(big, config=small_config()).source.max_pixels == 2**28 == decode.MAX_IMAGE_PIXELS
    with pytest.raises(ImageTooLargeError, match="b.png"):
        SidarDataset(big, config=small_config(max_image_pixels=399)).source.painting(0, (4, 4))


def test_pillows_process_wide_limit_is_neither_changed_nor_bypassed(tmp_path, monkeypatch):
    # The former code lifted PIL.Image.MAX_IMAGE_PIXELS (process-wide) around every decode.
    path = _solid(tmp_path / "b.png", BLUE, size=(60, 40))  # 2400 pixels
    seen = []
    real_open = Image.open

    def spy(fp, *args, **kwargs):
        seen.append(Image.MAX_IMAGE_PIXELS)
        return real_open(fp, *args, **kwargs)

    monkeypatch.setattr(Image, "open", spy)
    monkeypatch.setattr(Image, "MAX_IMAGE_PIXELS", 1000)  # Pillow refuses above 2000 pixels
    with pytest.raises(ValueError, match=r"b\.png.*Pillow refuses it .*2400 pixels.*PIL\.Image\.MAX_IMAGE_PIXELS"):
        make_source(path).painting(0, (4, 4))
    assert seen == [1000] and Image.MAX_IMAGE_PIXELS == 1000
    monkeypatch.setattr(Image, "MAX_IMAGE_PIXELS", None)  # a program that lifted Pillow's limit: ours decides
    assert (make_source(path).painting(0, (4, 4)) == BLUE).all()
    with pytest.raises(ImageTooLargeError, match="2400 pixels"):
        make_source(path, max_pixels=2399).painting(0, (4, 4))


def _png_bomb(path: Path, side: int = 100_000) -> Path:
    """A PNG whose header claims ``side x side`` 8-bit RGB pixels, with a short zlib stream of zeros."""
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    header = struct.pack(">IIBBBBB", side, side, 8, 2, 0, 0, 0)
    stream = zlib.compress(bytes(1_200_000), 9)
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", stream) + chunk(b"IEND", b""))
    return path


BOMB_CHILD = """
import json, resource, sys, time, warnings
resource.setrlimit(resource.RLIMIT_AS, (4 << 30, 4 << 30))  # a regression fails here, not the machine
from PIL import Image
from sidar_torch import SidarDataset, load_config
if sys.argv[2] == "lifted":
    Image.MAX_IMAGE_PIXELS = None  # a program that lifted Pillow's own limit: max_image_pixels decides
for on_bad_image in ("raise", "skip"):
    config = load_config("misaligned", image_size=(24, 32), n_views=1, on_bad_image=on_bad_image)
    dataset = SidarDataset(source=sys.argv[1], config=config)
    start = time.perf_counter()
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            dataset.sample(0)
    except Exception as exc:
        print(json.dumps({"error": f"{type(exc).__name__} {exc}", "warnings": [str(w.message) for w in caught],
                          "seconds": time.perf_counter() - start}))
"""


@pytest.mark.parametrize("pillow_limit", ["default", "lifted"])
def test_a_png_bomb_is_refused_from_its_header_in_a_memory_capped_child(tmp_path, pillow_limit):
    # issue 25 item 1: a 1.2 KB PNG claiming 100000 x 100000 pixels took 21.5 GB before the OOM killer.
    bomb = _png_bomb(tmp_path / "b.png")
    assert bomb.stat().st_size < 2000
    run = subprocess.run([sys.executable, "-c", BOMB_CHILD, str(bomb), pillow_limit],
                         capture_output=True, text=True, timeout=300, cwd=Path(__file__).resolve().parents[2])
    assert run.returncode == 0, run.stderr[-2000:]
    strict, lenient = (json.loads(line) for line in run.stdout.splitlines())
    for result in (strict, lenient):
        assert str(bomb) in result["error"] and "10000000000 pixels" in result["error"], result
        assert result["seconds"] < 5.0
    if pillow_limit == "lifted":
        assert strict["error"].startswith("ImageTooLargeError") and "max_image_pixels=268435456" in strict["error"]
    else:
        assert strict["error"].startswith("ValueError cannot decode image file") and "Pillow refuses" in strict["error"]
    assert lenient["error"].startswith("ValueError on_bad_image='skip', but none of the 1 images")
    assert len(lenient["warnings"]) == 1 and str(bomb) in lenient["warnings"][0]


# --------------------------------------------------------------------------- tensors, lists, datasets


def test_float_tensor_is_rounded_to_uint8():
    tensor = torch.tensor([0.0, 0.5, 1.0 / 255, 0.998, 1.0]).reshape(1, 1, 5).expand(3, 1, 5)
    out = make_source(tensor).painting(0, (1, 5))
    assert out[0, :, 0].tolist() == [0, 128, 1, 254, 255]


def test_tensor_paintings_index_the_batch():
    images = torch.stack([torch.full((3, 6, 9), i / 10) for i in range(4)])
    source = make_source(images)
    assert len(source) == 4
    assert [int(source.painting(i, (3, 3))[1, 1, 0]) for i in range(4)] == [0, 26, 51, 76]


@pytest.mark.parametrize(
    "tensor, message",
    [
        (torch.rand(4, 4), r"\(N, 3, h, w\) or \(3, h, w\), got \(4, 4\)"),
        (torch.rand(1, 1, 3, 4, 4), r"got \(1, 1, 3, 4, 4\)"),
        (torch.rand(2, 4, 5, 5), r"got \(2, 4, 5, 5\)"),
        (torch.rand(5, 5, 3), r"got \(5, 5, 3\)"),
        (torch.rand(3, 0, 4), "empty"),
        (torch.tensor(float("nan")).expand(3, 2, 2), "must be finite, got NaN"),
        (torch.tensor(float("inf")).expand(3, 2, 2), "must be finite, got NaN or infinite"),
        (torch.full((3, 2, 2), 1.5), r"must be in \[0, 1\], got range \[1.5, 1.5\]"),
        (torch.full((3, 2, 2), -0.1), r"must be in \[0, 1\]"),
        (torch.zeros(3, 2, 2, dtype=torch.int64), "dtype must be a float type or torch.uint8, got torch.int64"),
        (torch.zeros(3, 2, 2, dtype=torch.bool), "dtype must be a float type or torch.uint8, got torch.bool"),
    ],
)
def test_invalid_tensors_raise_value_error(tensor, message):
    with pytest.raises(ValueError, match=message):
        make_source(tensor)


@pytest.mark.parametrize("bad", [float("nan"), float("inf"), float("-inf")])
def test_one_non_finite_value_anywhere_raises(bad):
    for position in (0, 8, 5000, 3 * 64 * 64 - 1):  # the one-pass check meets it in any lane of its loop
        tensor = torch.rand(3, 64, 64)
        tensor.view(-1)[position] = bad
        with pytest.raises(ValueError, match="must be finite, got NaN or infinite"):
            make_source(tensor)


def test_half_precision_tensor_is_accepted():
    out = make_source(torch.ones(3, 4, 4, dtype=torch.float16)).painting(0, (4, 4))
    assert (out == 255).all()


def test_list_of_pil_and_tensors_keeps_order_and_sizes():
    items = [
        Image.new("RGB", (50, 20), RED),
        torch.zeros(3, 7, 9, dtype=torch.uint8),
        torch.ones(3, 31, 13),
        Image.new("RGB", (3, 90), BLUE),
    ]
    source = make_source(items)
    expected = [RED, (0, 0, 0), (255, 255, 255), BLUE]
    for index, color in enumerate(expected):
        out = source.painting(index, (40, 320))
        assert out.shape == (40, 320, 3) and (out == color).all()


def test_invalid_item_tensor_is_rejected_naming_its_position():
    with pytest.raises(ValueError, match=r"painting item 1 must have shape \(3, h, w\), got \(2, 3, 4, 4\)"):
        make_source([torch.rand(3, 4, 4), torch.rand(2, 3, 4, 4)])
    images = torch.rand(3, 3, 4, 4)
    images[2, 0, 0, 0] = float("nan")
    with pytest.raises(ValueError, match="painting item 2 values must be finite"):
        make_source(PairDataset(images)).painting(2, (4, 4))


def test_dataset_of_tensor_label_pairs():
    images = torch.rand(3, 3, 25, 35)
    source = make_source(PairDataset(images))
    assert len(source) == 3
    expected = np.round(images[2].permute(1, 2, 0).numpy() * 255).astype(np.uint8)
    np.testing.assert_array_equal(source.painting(2, (25, 35)), expected)


def test_dataset_of_pil_images():
    source = make_source(PilDataset())
    assert (source.painting(1, (20, 31)) == (10, 50, 90)).all()


def test_dataset_with_unsupported_items_raises_type_error():
    source = make_source(BadItemDataset())
    with pytest.raises(TypeError, match="str"):
        source.painting(0, (4, 4))


# --------------------------------------------------------------------------- paths, links, bad images in workers


def test_a_folder_spelled_relative_or_absolute_is_the_same_source(tmp_path, monkeypatch):
    (tmp_path / "photos").mkdir()
    _solid(tmp_path / "photos" / "a.png", RED)
    monkeypatch.chdir(tmp_path)
    relative, absolute = make_source("photos"), make_source(tmp_path / "photos")
    assert relative.paths == absolute.paths == (str(tmp_path / "photos" / "a.png"),)
    assert make_source(["./photos/../photos/a.png"]).paths == absolute.paths


def test_symlinked_subfolders_are_followed_and_loops_are_not(tmp_path):
    elsewhere, photos = tmp_path / "elsewhere", tmp_path / "photos"
    elsewhere.mkdir(), photos.mkdir()
    for k in range(20):
        _solid(elsewhere / f"{k:02d}.png", RED)
    _solid(photos / "own.png", RED)
    (photos / "linked").symlink_to(elsewhere, target_is_directory=True)
    (elsewhere / "back").symlink_to(tmp_path, target_is_directory=True)  # a loop: elsewhere/back/elsewhere/...
    (photos / "self").symlink_to(photos, target_is_directory=True)  # a loop onto itself
    source = make_source(photos)
    assert len(source) == 21  # own.png and the 20 linked ones, each once
    assert sorted(Path(p).name for p in source.paths) == sorted(["own.png"] + [f"{k:02d}.png" for k in range(20)])


def test_a_folder_reached_by_many_links_is_walked_once(tmp_path, monkeypatch):
    # issue 25 item 6: two links per level reach 2**depth paths (depth 16 listed for more than 300 s).
    depth = 12
    levels = [tmp_path / f"level{k}" for k in range(depth + 1)]
    for level in levels:
        level.mkdir()
    for upper, lower in zip(levels, levels[1:]):
        for link in "ab":
            (upper / link).symlink_to(lower, target_is_directory=True)
    _solid(levels[-1] / "deep.png", RED)
    walked = []
    real_walk = os.walk

    def spy(*args, **kwargs):
        for step in real_walk(*args, **kwargs):
            walked.append(step[0])
            yield step

    monkeypatch.setattr(os, "walk", spy)
    source = make_source(levels[0])
    assert len(walked) == depth + 1  # each real folder once
    assert source.paths == (str(levels[0].joinpath(*["a"] * depth, "deep.png")),)  # the first path in sorted order


def test_the_bad_image_warning_points_at_the_image(tmp_path):
    # issue 20 item 6: it pointed at a line of dataset.py, the same for every file.
    _solid(tmp_path / "a.png", RED)
    (tmp_path / "b.png").write_text("not an image")
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        make_source(tmp_path, on_bad_image="skip").painting(1, (4, 4))
    [warning] = record
    assert warning.category is BadImageWarning
    assert (warning.filename, warning.lineno) == (str(tmp_path / "b.png"), 0)
    assert "source.scan()" in str(warning.message)


def test_scan_drops_unreadable_images_so_every_index_shows_its_own_painting(tmp_path):
    # issue 20 item 6: a skipped image's index showed the next image, so two samples showed one painting.
    pixels = [_random_rgb(8, 8, seed) for seed in range(4)]
    paths = [_save(Image.fromarray(p), tmp_path / f"{name}.png") for p, name in zip(pixels, "abcd")]
    paths[1].write_text("not an image")
    source = make_source(tmp_path, on_bad_image="skip")
    assert len(source) == 4
    with pytest.warns(BadImageWarning, match="b.png"):
        assert list(source.scan()) == [str(paths[1])]
    assert len(source) == 3 and list(source.kept) == [0, 2, 3]
    for copy in (source, pickle.loads(pickle.dumps(source))):  # as DataLoader workers get it
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # the dropped image is neither read nor warned about again
            got = [copy.painting(index, (8, 8)) for index in range(4)]
        for painting, expected in zip(got, [pixels[0], pixels[2], pixels[3], pixels[0]]):
            np.testing.assert_array_equal(painting, expected)
    strict = make_source(tmp_path)  # "raise": the scan only reports (silent: warned once in this process)
    assert list(strict.scan()) == [str(paths[1])]
    assert len(strict) == 4
    with pytest.raises(ValueError, match="b.png"):
        strict.painting(1, (8, 8))
    for path in paths:
        path.write_text("not an image")
    with pytest.warns(BadImageWarning), pytest.raises(ValueError, match="none of the 4 images"):
        make_source(tmp_path, on_bad_image="skip").scan()


def test_scan_drops_unreadable_dataset_items():
    lenient = make_source(FlakyDataset(), on_bad_image="skip")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", BadImageWarning)  # warned once per process: maybe by another test
        assert sorted(lenient.scan()) == ["dataset item 1", "dataset item 2"]
    assert len(lenient) == len(FlakyDataset()) - 2
    assert (lenient.painting(1, (4, 4)) == 76).all()  # item 3: round(0.3 * 255)


@pytest.mark.gl
def test_scan_finds_bad_images_in_the_main_process_and_workers_stay_silent(tmp_path, capfd):
    for name in "abcd":
        _solid(tmp_path / f"{name}.png", RED)
    (tmp_path / "b.png").write_text("not an image")
    dataset = SidarDataset(tmp_path, config=small_config(on_bad_image="skip", n_views=1, image_size=(16, 16),
                                                         n_occluders=(0, 0), n_lights=(0, 0)), length=4)
    with pytest.warns(BadImageWarning, match="b.png"):
        assert dataset.source.scan() == {str(tmp_path / "b.png"): dataset.source.bad_images[str(tmp_path / "b.png")]}
    capfd.readouterr()
    batches = list(torch.utils.data.DataLoader(dataset, batch_size=None, num_workers=2))
    assert sorted(int(b["index"]) for b in batches) == [0, 1, 2, 3]
    assert "unreadable" not in capfd.readouterr().err  # the workers knew b.png from the scan
