"""The table of export layouts (``sidar_torch.io.layouts``): every layout answers the one interface
(:class:`sidar_torch.io.layout.Layout`), written and read back through it alone, without rendering;
the manifest's ``layout`` names are the table's keys; a painting source describes itself."""

import hashlib
import json
from functools import partial

import numpy as np
import pytest

from conftest import small_config
from sidar_torch.io import Layout, WriteUnit
from sidar_torch.io.codecs import decode
from sidar_torch.io.entries import sample_from_entries
from sidar_torch.io.layouts import LAYOUTS, layout_for, recorded_layout
from sidar_torch.io.manifest import read_manifest, write_manifest
from sidar_torch.sample import SampleArrays
from sidar_torch.paintings import ImageFiles, ProceduralPaintings

SHARD_SIZES = {"folders": None, "shards": 2, "paper": None}
"""A ``shard_size`` of each layout of the table (``export_dataset``'s argument, with ``layout``, that picks it)."""

CONFIG = {"image_size": [6, 8], "n_views": 2, "opacity_output": True}
"""The recorded config fields the entries of :func:`sample` need (their size; opacities are written)."""


def sample(index, n_views=2, size=(6, 8)):
    """Random :class:`SampleArrays` of ``n_views`` views of ``size`` pixels, opacities included, of
    numbers the reader accepts (homographies: the identity on the diagonal, as a rendered sample's;
    pinhole intrinsics, rotations)."""
    rng = np.random.default_rng(index)
    pixels = partial(rng.integers, 0, 256, dtype=np.uint8)
    homographies = rng.normal(size=(n_views, n_views, 3, 3))
    homographies[np.arange(n_views), np.arange(n_views)] = np.eye(3)
    return SampleArrays(images=pixels((n_views, *size, 3)), masks=pixels((n_views, *size)),
                        opacities=pixels((n_views, *size)), label=pixels((*size, 3)),
                        homographies=homographies, homography_error=rng.random(),
                        K=intrinsics(rng, n_views), R=rotations(rng, n_views),
                        t=rng.normal(size=(n_views, 3)), index=index)


def intrinsics(rng, count):
    """``(count, 3, 3)`` random pinhole intrinsics ``[[fx, s, cx], [0, fy, cy], [0, 0, 1]]``, ``fx, fy > 0``."""
    K = np.triu(rng.uniform(1, 9, (count, 3, 3)))
    K[:, 2, 2] = 1
    return K


def rotations(rng, count):
    """``(count, 3, 3)`` random rotations (det 1)."""
    Q = np.linalg.qr(rng.normal(size=(count, 3, 3)))[0]
    return Q * np.sign(np.linalg.det(Q))[:, None, None]


def tree_bytes(out):
    return {path.relative_to(out): path.read_bytes() for path in sorted(out.rglob("*")) if path.is_file()}


def test_every_layout_of_the_table_has_a_shard_size_here():
    assert set(SHARD_SIZES) == set(LAYOUTS)
    assert all(layout.name == name for name, layout in LAYOUTS.items())


@pytest.mark.parametrize("name", sorted(SHARD_SIZES))
def test_a_layout_writes_and_reads_back_samples_through_the_interface_alone(tmp_path, name):
    layout = layout_for(SHARD_SIZES[name], name)
    assert isinstance(layout, Layout) and layout.name == name and layout.shard_size == SHARD_SIZES[name]
    samples = {index: sample(index) for index in (3, 4, 5)}
    wanted = range(3, 6)
    assert layout.present(tmp_path, wanted) == (set(), frozenset())

    units = layout.groups(list(wanted), frozenset())
    assert all(isinstance(unit, WriteUnit) for unit in units)
    assert [index for unit in units for index in unit.indices] == list(wanted)
    rendered, written = [], []
    for unit in units:
        layout.write(tmp_path, unit, lambda index: rendered.append(index) or samples[index],
                     lambda: written.append(True))
    assert rendered == list(wanted) and len(written) == len(wanted)
    assert layout.present(tmp_path, wanted) == (set(wanted), frozenset())

    before = tree_bytes(tmp_path)
    for unit in units:  # a retry: everything is there, nothing is rendered, the bytes stay
        layout.write(tmp_path, unit, lambda index: pytest.fail(f"rendered {index} again"), lambda: None)
    assert tree_bytes(tmp_path) == before

    items = layout.sequences(tmp_path)
    assert [index for index, _ in items] == list(wanted)
    for index, where in items:
        def read(entry, shape=None, check=None, where=where):
            value = decode(entry, layout.read(tmp_path, where, entry, 2**20)[1], shape)
            return value if check is None else check(value)

        back = sample_from_entries(read, index, CONFIG, partial(layout.read_homographies, read))
        for field, value in vars(samples[index]).items():
            np.testing.assert_array_equal(getattr(back, field), value, err_msg=f"{name}: {field} of {index}")
        with pytest.raises(FileNotFoundError):
            layout.read(tmp_path, where, "no-such-entry.png", 2**20)


@pytest.mark.parametrize("name", sorted(SHARD_SIZES))
def test_the_manifest_records_the_tables_name_and_gives_the_layout_back(tmp_path, name):
    layout = layout_for(SHARD_SIZES[name], name)
    write_manifest(tmp_path, 0, ProceduralPaintings(10), small_config().to_dict(), layout)
    manifest = read_manifest(tmp_path)
    assert manifest["layout"] == name and manifest["shard_size"] == SHARD_SIZES[name]
    assert recorded_layout(manifest) == layout


@pytest.mark.parametrize("name", sorted(SHARD_SIZES))
def test_a_layout_refuses_another_layouts_shard_size(name):
    other = next(shard_size for shard_size in SHARD_SIZES.values() if shard_size != SHARD_SIZES[name])
    with pytest.raises(ValueError, match=r"field 'shard_size': expected .*, got "):
        LAYOUTS[name].from_record(other)


def test_a_painting_source_describes_itself():
    files = ImageFiles(["/paintings/a.png", "/paintings/b.png"], crop="none")
    assert files.describe() == {
        "type": "ImageFiles", "paintings": 2, "crop": "none", "first_path": "/paintings/a.png",
        "paths_sha256": hashlib.sha256(b"/paintings/a.png\n/paintings/b.png").hexdigest()}
    assert ProceduralPaintings(7).describe() == {"type": "ProceduralPaintings", "paintings": 7}


def test_a_rerun_resumes_an_export_recorded_before_a_config_field_existed_and_refuses_a_change(tmp_path):
    """An export (or a test set's cache) recorded before a field was added holds no value for it: it
    drew what the field's default draws, so a rerun resumes it; any other change is still refused."""
    layout = layout_for(None, "folders")
    config = small_config().to_dict()
    write_manifest(tmp_path, 0, ProceduralPaintings(10), config, layout)
    recorded = json.loads((tmp_path / "export.json").read_text())
    del recorded["config"]["normals_output"]  # as written before normals existed
    (tmp_path / "export.json").write_text(json.dumps(recorded))
    write_manifest(tmp_path, 0, ProceduralPaintings(10), config, layout)  # resumes
    with pytest.raises(ValueError, match=r"config.normals_output: False there, True now"):
        write_manifest(tmp_path, 0, ProceduralPaintings(10), {**config, "normals_output": True}, layout)
