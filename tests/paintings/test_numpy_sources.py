"""NumPy images wherever PIL images and tensors are taken (issue 34 item 7: OpenCV and albumentations
hand out ``(h, w, 3)`` uint8 arrays, which were refused with a TypeError), and refusals of ambiguous
layouts and ranges that name the call fixing them."""

import numpy as np
import pytest
import torch
from PIL import Image

from sidar_torch import SidarDataset, load_config
from sidar_torch.paintings import ImageList, TensorPaintings, make_source

SIZE = (12, 16)
RNG = np.random.default_rng(0)
HWC = RNG.integers(0, 256, (4, 20, 30, 3), dtype=np.uint8)
"""Four channels-last RGB images."""


def paintings(source, count):
    return [source.painting(i, SIZE) for i in range(count)]


def reference(images):
    """The paintings of the same pixels given as a channels-first tensor."""
    return paintings(make_source(torch.from_numpy(np.ascontiguousarray(images.transpose(0, 3, 1, 2)))), len(images))


@pytest.mark.parametrize("form", ["batch", "one", "list", "float32", "float64", "grey", "grey-1", "dataset"])
def test_numpy_images_give_the_paintings_of_the_same_pixels_as_tensors(form):
    expected = reference(HWC)
    if form == "batch":
        source, want = HWC, expected
    elif form == "one":
        source, want = HWC[1], expected[1:2]
    elif form == "list":
        source, want = [HWC[0], torch.from_numpy(HWC[1].transpose(2, 0, 1).copy()), Image.fromarray(HWC[2])], expected[:3]
    elif form.startswith("float"):
        source, want = HWC.astype(form) / 255, expected
    elif form.startswith("grey"):
        grey = HWC[..., 0]
        source = grey[0] if form == "grey" else grey[0][:, :, None]
        want = reference(np.repeat(grey[:1, :, :, None], 3, axis=3))
    else:  # a dataset of (image, label) items, as an albumentations pipeline hands them out
        source, want = type("Items", (), {"__len__": lambda self: 4, "__getitem__": lambda self, i: (HWC[i], 7)})(), expected
    got = paintings(make_source(source), len(want))
    assert all(np.array_equal(a, b) for a, b in zip(got, want)), form


def test_a_dataset_takes_a_numpy_source():
    ds = SidarDataset(source=HWC, config=load_config("misaligned", image_size=SIZE, n_views=2), seed=0)
    assert isinstance(ds.source, TensorPaintings) and len(ds.source) == 4
    assert np.array_equal(ds.source.painting(2, SIZE), reference(HWC)[2])
    assert isinstance(make_source([HWC[0], HWC[1]]), ImageList)


@pytest.mark.parametrize("source, message", [
    (HWC[0].transpose(2, 0, 1), r"got \(3, 20, 30\); channels first \(c, h, w\)\? use x.transpose\(1, 2, 0\)"),
    (HWC.transpose(0, 3, 1, 2), r"channels first \(c, h, w\)\? use x.transpose\(0, 2, 3, 1\)"),
    (HWC[..., 0], r"a batch of grey images \(N, h, w\)\? use x\[..., None\]"),
    (HWC.astype(np.uint16) * 257, r"got uint16; 16-bit integers\? use x / 65535"),
    (HWC.astype(np.float32), r"got range \[0.0, 255.0\]; 8-bit values 0..255 as floats\? use x / 255"),
    (torch.from_numpy(HWC[0]), r"got \(20, 30, 3\); channels last \(h, w, c\), as OpenCV, albumentations and PIL give "
                               r"them\? use x.permute\(2, 0, 1\)"),
    (torch.from_numpy(HWC), r"use x.permute\(0, 3, 1, 2\)"),
    (torch.from_numpy(HWC).permute(0, 3, 1, 2) / 127.5 - 1, r"values in \[-1, 1\]\? use \(x \+ 1\) / 2"),
    (torch.full((1, 3, 4, 4), 255.0), r"8-bit values 0..255 as floats\? use x / 255"),
], ids=["chw", "nchw", "grey-batch", "uint16", "float-255", "hwc-tensor", "nhwc-tensor", "minus-one", "tensor-255"])
def test_ambiguous_layouts_and_ranges_are_refused_naming_the_fix(source, message):
    with pytest.raises(ValueError, match=message):
        make_source(source)
