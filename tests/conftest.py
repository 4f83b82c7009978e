"""Shared test settings: small images keep rendering fast on CPU."""

import hashlib
from pathlib import Path

import numpy as np
import pytest
import torch

import sidar_torch  # noqa: F401  (selects the OSMesa platform before anything imports OpenGL)
from sidar_torch.render import render_in_this_process
from sidar_torch import geometry, load_config
from sidar_torch.scene import Camera, Material, SceneSequence, ViewScene

render_in_this_process()
"""The suite renders in its own process, where it inspects renderers; the default for a process that may fork,
a render process (``sidar_torch.render.process``), is tested in subprocesses (tests/render/test_render_process.py)."""

SMALL = (96, 128)

TINY = {"image_size": (24, 32), "n_views": 2, "shadow_map_size": 256}
"""Config overrides for samples that export and read back quickly."""

WHITE = Material(np.ones(4), 0.0, 1.0)
"""A white painting material, glTF's default dielectric (4 % specular)."""

LAMBERTIAN = Material(np.ones(4), 0.0, 1.0, specular=0.0)
"""A white, purely diffuse painting material."""


def pytest_addoption(parser):
    parser.addoption("--runslow", action="store_true",
                     help="also run the tests marked slow (benchmark smoke tests, long process tests); CI does")


def pytest_collection_modifyitems(config, items):
    """Tests marked ``slow`` are skipped unless ``--runslow`` is given (``.ci/run`` gives it)."""
    if config.getoption("--runslow"):
        return
    skip = pytest.mark.skip(reason="slow: run with --runslow (as CI does)")
    for item in items:
        if "slow" in item.keywords:
            item.add_marker(skip)


@pytest.fixture(autouse=True)
def _no_gl_unless_marked(request, monkeypatch):
    """A test not marked ``gl`` may not render in this process: the renderer's loader raises (every
    renderer, shared or not, is reached through it), so an unmarked rendering test fails loudly instead of slipping into the fast
    ``-m "not gl"`` subset (tests that render in a child process are marked by hand)."""
    if request.node.get_closest_marker("gl") is not None:
        return

    def refuse(*args, **kwargs):
        raise RuntimeError(f"{request.node.nodeid} renders but is not marked 'gl' (pytest.mark.gl)")

    import sidar_torch.render as render

    monkeypatch.setattr(render, "_renderer", refuse)


def small_config(preset="misaligned", **overrides):
    """A preset at 96 x 128 with 3 views, unless overridden."""
    return load_config(preset, **{"image_size": SMALL, "n_views": 3, **overrides})


def textured_painting(size, seed=0):
    """``(H, W, 3)`` uint8 random texture: every pixel differs from its neighbours."""
    return np.random.default_rng(seed).integers(0, 256, (*size, 3), dtype=np.uint8)


def render_flat_painting(occluders=(), lights=(), plane=WHITE, ambient=0.0, painting=200, size=SMALL, camera=None,
                         renderer=None, **settings):
    """One view of a flat painting through the reference camera (height 0.9 unless ``camera`` is
    given): ``painting`` a grey level, an RGB triple or an ``(H, W, 3)`` uint8 array. Rendered by
    ``renderer``, else by this process's shared renderer for ``RenderSettings(size, **settings)``
    returns its ``RenderedSequence``."""
    from sidar_torch.render import RenderSettings, shared_renderer

    camera = camera or Camera(*geometry.reference_camera(size, 0.9))
    view = ViewScene(camera, tuple(lights), tuple(occluders), plane, ambient)
    texture = np.broadcast_to(np.asarray(painting, np.uint8), (*size, 3)).copy()
    renderer = renderer or shared_renderer(RenderSettings(size, **settings))
    return renderer.render(SceneSequence(size, (view,)), texture)


def same_tensor(a, b):
    """Whether tensors ``a`` and ``b`` have the same dtype, shape and values, NaN equal to NaN (the
    ``flow_to_reference`` output holds NaN where it is not valid)."""
    if a.dtype != b.dtype or a.shape != b.shape:
        return False
    if not a.is_floating_point():
        return torch.equal(a, b)
    return torch.equal(a.isnan(), b.isnan()) and torch.equal(a.nan_to_num(0.0), b.nan_to_num(0.0))


def assert_same_batch(a, b):
    """Two sample dicts (or batches) of tensors have the same keys and equal tensors (naming the first key that differs)."""
    assert a.keys() == b.keys()
    for key in a:
        assert same_tensor(a[key], b[key]), key


def assert_same_sample(read, rendered):
    """A sample read back (``ExportedDataset``) is ``rendered``: the same keys, tensors of the same
    dtype, shape and values, other values of the same type and value (naming the key that differs)."""
    assert set(read) == set(rendered)
    for key, value in rendered.items():
        if isinstance(value, torch.Tensor):
            assert read[key].dtype == value.dtype and read[key].shape == value.shape, key
            assert same_tensor(read[key], value), key
        else:
            assert type(read[key]) is type(value) and read[key] == value, key


def sample_digest(sample):
    """``{key: SHA-256 hex}`` of a sample dict: tensors by dtype, shape and bytes, other values by
    ``repr``. Equal digests mean byte-identical samples; being strings, they compare across
    processes, and a mismatch names the key."""
    digests = {}
    for key, value in sample.items():
        if isinstance(value, torch.Tensor):
            value = value.contiguous()
            data = f"{value.dtype} {tuple(value.shape)} ".encode() + value.numpy().tobytes()
        else:
            data = repr(value).encode()
        digests[key] = hashlib.sha256(data).hexdigest()
    return digests


@pytest.fixture
def rng():
    return np.random.default_rng(1234)


def child_pids(pid: int) -> set[int]:
    """Pids of the live processes whose parent is ``pid`` (from ``/proc``; Linux)."""
    found = set()
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid and fields[0] != "Z":
            found.add(int(stat.parent.name))
    return found


def alive(pid: int) -> bool:
    """Whether process ``pid`` exists and is not a zombie (from ``/proc``)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False
