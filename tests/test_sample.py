"""The sample contract (``sidar_torch.sample``): the table is what samples hold, the arrays refuse
what they cannot be, and no other module of the package keeps a key list of its own."""

import itertools
import re
from pathlib import Path

import numpy as np
import pytest
import torch
from torch.utils.data import DataLoader

import sidar_torch
from sidar_torch import SidarAugment, SidarDataset, load_config
from sidar_torch.render import RenderSettings, shared_renderer
from sidar_torch.sample import (KEYS, SampleArrays, batch_homographies, present_keys, render_sample,
                                sequence_homographies, stack_arrays, stack_samples)

import test_hard_cases as hard_cases
from conftest import small_config

pytestmark = pytest.mark.gl  # renders


def expected_shape(key, V, H, W):
    """The table's shape text, e.g. ``"(V, 3, H, W)"``, with the sizes filled in."""
    return eval(key.shape.replace("V", str(V)).replace("H", str(H)).replace("W", str(W)))  # noqa: S307


@pytest.mark.parametrize("opacity_output", [False, True])
def test_the_table_is_what_a_sample_holds(opacity_output):
    config = small_config(n_views=3, image_size=(24, 32), opacity_output=opacity_output)
    sample = SidarDataset(config=config, seed=1).sample(2)
    keys = present_keys(config)
    assert list(sample) == [key.name for key in keys]  # names and order
    assert ("opacities" in sample) == opacity_output
    for key in keys:
        value = sample[key.name]
        if isinstance(value, torch.Tensor):
            assert tuple(value.shape) == expected_shape(key, 3, 24, 32), key.name
            assert value.dtype == torch.float32, key.name
            assert key.dtype.startswith("float32") or key.dtype == "geometry_dtype", key.name
        else:
            assert key.shape == "()" and type(value).__name__ == key.dtype.split()[0], key.name


def test_sample_arrays_name_the_field_of_a_wrong_shape_or_dtype():
    arrays = SidarDataset(config=small_config(n_views=2, image_size=(8, 12)), seed=0).sample_arrays(0)
    fields = vars(arrays)
    bad = {
        "masks": (arrays.masks.astype(bool), r"SampleArrays\.masks: expected shape \(2, 8, 12\) uint8, got .* bool"),
        "label": (arrays.label[..., :2], r"SampleArrays\.label: expected shape \(8, 12, 3\)"),
        "homographies": (arrays.homographies.astype(np.float32), r"SampleArrays\.homographies: .* float64"),
        "opacities": (np.zeros((3, 8, 12), np.uint8), r"SampleArrays\.opacities: expected shape \(2, 8, 12\)"),
        "images": (arrays.images[0], r"SampleArrays\.images: expected a \(V, H, W, 3\) uint8 array, got \(8, 12, 3\)"),
        "t": (arrays.t.tolist(), r"SampleArrays\.t: expected shape \(2, 3\) float64, got list"),
    }
    for name, (value, match) in bad.items():
        with pytest.raises(ValueError, match=match):
            SampleArrays(**{**fields, name: value})
    with pytest.raises(ValueError, match=r"geometry_dtype: expected one of \('float32', 'float64'\), got 'half'"):
        arrays.to_tensors("half")


def test_to_tensors_converts_8_bit_values_exactly():
    config = small_config(n_views=2, image_size=(8, 12), opacity_output=True)
    arrays = SidarDataset(config=config, seed=0).sample_arrays(0)
    sample = arrays.to_tensors()
    assert torch.equal(sample["images"].mul(255).round().to(torch.uint8).permute(0, 2, 3, 1),
                       torch.from_numpy(arrays.images))
    assert torch.equal(sample["masks"][:, 0] == 1, torch.from_numpy(arrays.masks == 255))
    assert set(np.unique(arrays.masks)) <= {0, 255}
    assert torch.equal(sample["opacities"][:, 0].mul(255).round().to(torch.uint8), torch.from_numpy(arrays.opacities))
    assert torch.equal(sample["homographies"], torch.from_numpy(arrays.homographies).float())


def test_stack_samples_batches_every_key():
    ds = SidarDataset(config=small_config(n_views=2, image_size=(8, 12)), seed=0)
    samples = [ds.sample(i) for i in range(3)]
    batch = stack_samples(samples)
    assert list(batch) == list(samples[0])
    assert batch["images"].shape == (3, 2, 3, 8, 12) and torch.equal(batch["K"][1], samples[1]["K"])
    assert batch["homography_error"].dtype == torch.float64 and batch["homography_error"].shape == (3,)
    assert batch["index"].tolist() == [0, 1, 2] and batch["index"].dtype == torch.int64


@pytest.mark.parametrize("pixel_dtype", [torch.float32, torch.float64, torch.uint8])
def test_stack_arrays_is_stack_samples_of_each_samples_tensors(pixel_dtype):
    """Values, dtypes, shapes and strides: a batch converted at once is the batch of the samples'
    own tensors, whatever the pixels' dtype, the optional pixel keys included."""
    config = small_config(n_views=2, image_size=(8, 12), opacity_output=True, shadow_mask_output=True,
                          shadow_free_output=True)
    ds = SidarDataset(config=config, seed=0)
    arrays = [ds.sample_arrays(i) for i in range(3)]
    batch = stack_arrays(arrays, "float64", pixel_dtype)
    expected = stack_samples([a.to_tensors("float64", pixel_dtype) for a in arrays])
    assert list(batch) == list(expected) == [key.name for key in present_keys(config)]
    for key, value in expected.items():
        assert value.dtype == batch[key].dtype and value.shape == batch[key].shape, key
        assert torch.equal(value, batch[key]), key
        assert value.stride() == batch[key].stride(), key
    assert batch["images"].dtype == pixel_dtype and batch["homographies"].dtype == torch.float64
    if pixel_dtype == torch.uint8:  # the stored 8-bit values themselves
        assert torch.equal(batch["images"][1], torch.from_numpy(arrays[1].images).permute(0, 3, 1, 2))
    else:  # k / 255 in that dtype
        assert torch.equal(batch["masks"][2, :, 0], torch.from_numpy(arrays[2].masks).to(pixel_dtype) / 255)


def test_stack_arrays_refuses_what_it_cannot_batch():
    ds = SidarDataset(config=small_config(n_views=2, image_size=(8, 12), opacity_output=True), seed=0)
    arrays = ds.sample_arrays(0)
    with pytest.raises(ValueError, match="stack_arrays: expected at least one sample"):
        stack_arrays([])
    without = SampleArrays(**{**vars(arrays), "opacities": None})
    with pytest.raises(ValueError, match="stack_arrays: opacities is present in some samples and not in others"):
        stack_arrays([arrays, without])
    with pytest.raises(ValueError, match="pixel_dtype: expected torch.uint8 or a float dtype, got torch.int32"):
        stack_arrays([arrays], pixel_dtype=torch.int32)


def test_no_other_module_of_the_package_keeps_a_list_of_sample_keys():
    """A line naming two or more sample keys as strings, other than as subscripts (``s["images"]``,
    reads of single keys), is a key list: only the contract's module (``sample/contract.py``) has them."""
    names = "|".join(re.escape(key.name) for key in KEYS)
    quoted = re.compile(rf"""(?<!\[)["']({names})["']""")
    package = Path(sidar_torch.__file__).parent
    offenders = []
    for path in sorted(package.rglob("*.py")):
        if path == package / "sample" / "contract.py":
            continue
        for number, line in enumerate(path.read_text().splitlines(), 1):
            if len(set(quoted.findall(line))) >= 2:
                offenders.append(f"{path.relative_to(package)}:{number}: {line.strip()}")
    assert not offenders, "\n".join(offenders)


# --------------------------------------------------------------------------- geometry_dtype (issue 13 item 9)

def chaining_error(H, cams, size):
    """Largest distance, in view-j pixels at the painting points views i and j both see, between
    ``H[i, j]`` and ``H[k, j] @ H[i, k]`` (in the homographies' own dtype), over all triples."""
    worst = 0.0
    for i, j, k in itertools.permutations(range(len(cams)), 3):
        _, xi, _ = hard_cases.shared_points(cams, size, i, j, 11)
        chained = (H[k, j] @ H[i, k]).double().numpy()
        direct = H[i, j].double().numpy()
        moved = hard_cases.transfer(chained, xi)[0] - hard_cases.transfer(direct, xi)[0]
        worst = max(worst, float(np.linalg.norm(moved, axis=1).max()))
    return worst


def test_float64_geometry_keeps_chained_homographies_exact_at_grazing_cameras():
    """Two cameras 0.009 and 0.004 above the painting, tilted 89.9 degrees: chaining float32
    homographies through a third view moves points by tens of pixels (measured 27.7), float64 by
    under 1e-6 px (measured 3e-8)."""
    size = hard_cases.SIZE
    cams = [hard_cases.reference(size, 0.9), hard_cases.camera(89.9, 30, 5.0, 60, size),
            hard_cases.camera(89.9, 150, 2.5, 60, size)]
    sequence = hard_cases.sequence(cams, size)
    painting = np.full((*size, 3), 128, np.uint8)
    for dtype, torch_dtype in (("float32", torch.float32), ("float64", torch.float64)):
        config = load_config("misaligned", image_size=size, n_views=3, shadow_map_size=256, geometry_dtype=dtype)
        sample = render_sample(shared_renderer(RenderSettings.from_config(config)), sequence, painting, config, 0)
        for key in ("homographies", "K", "R", "t"):
            assert sample[key].dtype == torch_dtype, (dtype, key)
        assert sample["images"].dtype == torch.float32
        error = chaining_error(sample["homographies"], cams, size)
        if dtype == "float32":
            assert error > 5.0, error
        else:
            assert error < 1e-6, error
            assert torch.equal(sample["homographies"], sequence_homographies(sequence)[0])


def test_float64_geometry_through_the_dataloader_and_augment():
    config = small_config(n_views=2, image_size=(24, 32), shadow_map_size=256, geometry_dtype="float64")
    ds = SidarDataset(config=config, seed=4, length=2)
    batch = next(iter(DataLoader(ds, batch_size=2)))
    for k in range(2):
        sample = ds.sample(k)
        for key in ("homographies", "K", "R", "t"):
            assert batch[key].dtype == torch.float64 and torch.equal(batch[key][k], sample[key]), key
        assert torch.equal(sample["homographies"], sequence_homographies(ds.scene(k))[0])
    out = SidarAugment(config, seed=0)(torch.rand(2, 3, 24, 32))
    assert out["homographies"].dtype == torch.float64 and out["K"].dtype == torch.float64
    assert out["images"].dtype == torch.float32 and out["homography_error"].dtype == torch.float64


def test_geometry_dtype_is_validated():
    with pytest.raises(ValueError, match=r"config field 'geometry_dtype': expected one of \('float32', 'float64'\)"):
        load_config("misaligned", geometry_dtype="float16")


def test_batch_homographies_are_each_sequences_own():
    ds = SidarDataset(config=small_config(n_views=3), seed=4)
    sequences = [ds.scene(k) for k in range(5)]
    for sequence, (H, error) in zip(sequences, batch_homographies(sequences)):
        alone, alone_error = sequence_homographies(sequence)
        assert torch.equal(H, alone) and error == alone_error and error < 1e-6
    other = SidarDataset(config=small_config(n_views=2), seed=4).scene(0)
    with pytest.raises(ValueError, match=r"sequences: expected at least one, all with the same number of views, "
                                         r"got \[3, 2\] views"):
        batch_homographies([sequences[0], other])
    with pytest.raises(ValueError, match="sequences: expected at least one"):
        batch_homographies([])
