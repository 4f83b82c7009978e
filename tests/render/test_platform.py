"""Platforms: EGL renders the pixels OSMesa renders; the renderer's own framebuffer gives the pixels
OSMesa's buffer gave; renderers on one EGL display outlive each other; a child forked after its parent
opened an EGL context is refused with what to do instead; a missing library or driver or a wrong device
number says what is wrong and what to install.

EGL runs in subprocesses: PyOpenGL fixes its platform at its first import, and this process
renders on OSMesa (``conftest`` imports ``sidar_torch`` first).
"""

import contextlib
import json
import os
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from OpenGL import GL

from sidar_torch.render import RenderSettings, SceneRenderer, passes
from sidar_torch.render.context import GL_PLATFORM
from sidar_torch.scene import sample_sequence

from conftest import SMALL, small_config, textured_painting

pytestmark = pytest.mark.gl  # renders

TESTS = Path(__file__).resolve().parents[1]  # tests/: conftest, for the child processes

SEQUENCES = [("misaligned", 0), ("paper_misaligned", 1)]
"""(preset, seed) pairs: lit views with shadows, masks, glossy and transparent occluders; both
presets give the renderer ``RenderSettings(SMALL)`` but for ``antialias`` (4 in ``paper_misaligned``;
these comparisons draw one sample per pixel)."""

RENDER_SEQUENCES = f"""
import json, sys
import numpy as np
sys.path.insert(0, {str(TESTS)!r})
import sidar_torch
from OpenGL import GL, platform
from sidar_torch.render import RenderSettings, SceneRenderer
from sidar_torch.scene import sample_sequence
from conftest import SMALL, small_config, textured_painting
renderer = SceneRenderer(RenderSettings(SMALL))
arrays = {{}}
for k, (preset, seed) in enumerate({SEQUENCES!r}):
    out = renderer.render(sample_sequence(small_config(preset), np.random.default_rng(seed)), textured_painting(SMALL, seed))
    arrays.update({{f"views{{k}}": out.views, f"masks{{k}}": out.masks, f"label{{k}}": out.label}})
np.savez(sys.argv[1], **arrays)
print(json.dumps([type(platform.PLATFORM).__name__, GL.glGetString(GL.GL_RENDERER).decode()]))
"""
"""Renders :data:`SEQUENCES` into the ``.npz`` file ``argv[1]``; prints the PyOpenGL platform and GL renderer."""


def run_on(platform, code, *args, **env):
    """Run ``code`` in a fresh interpreter on ``PYOPENGL_PLATFORM=platform``; the finished process.

    The child forks nothing, so it may use Mesa's on-disk shader cache (faster start-up).
    """
    env = {**os.environ, "PYOPENGL_PLATFORM": platform, "MESA_SHADER_CACHE_DISABLE": "false", **env}
    return subprocess.run([sys.executable, "-c", code, *map(str, args)], capture_output=True, text=True,
                          timeout=300, env=env)


def skip_unless_egl_opens(result):
    """Skip when the child could not open any EGL context; fail on any other error."""
    if "cannot open an offscreen OpenGL context on platform 'egl'" in result.stderr:
        pytest.skip(f"EGL unavailable here: {result.stderr.strip().splitlines()[-1]}")
    assert result.returncode == 0, result.stderr[-2000:]


def test_egl_renders_the_same_views_masks_and_label_as_osmesa(tmp_path):
    results = {p: run_on(p, RENDER_SEQUENCES, tmp_path / f"{p}.npz") for p in ("osmesa", "egl")}
    skip_unless_egl_opens(results["egl"])
    assert results["osmesa"].returncode == 0, results["osmesa"].stderr[-2000:]
    (osmesa_platform, osmesa_gl), (egl_platform, egl_gl) = (json.loads(results[p].stdout) for p in ("osmesa", "egl"))
    assert (osmesa_platform, egl_platform) == ("OSMesaPlatform", "EGLPlatform")
    assert egl_gl == osmesa_gl, f"EGL device 0 is {egl_gl}, OSMesa is {osmesa_gl}: not the same rasteriser"
    osmesa, egl = (np.load(tmp_path / f"{p}.npz") for p in ("osmesa", "egl"))
    for k, (_, seed) in enumerate(SEQUENCES):
        assert np.array_equal(egl[f"label{k}"], textured_painting(SMALL, seed))
        for name in ("views", "masks", "label"):
            assert np.array_equal(egl[f"{name}{k}"], osmesa[f"{name}{k}"]), f"{name} of sequence {k} differ"
        assert osmesa[f"masks{k}"].any() and not osmesa[f"masks{k}"].all()  # occluders and painting both seen


def test_closing_one_egl_renderer_leaves_another_working():
    # EGL has one display per device and process: pyrender's eglTerminate on closing one renderer
    # destroyed the contexts of all the others.
    code = f"""
import sys
import numpy as np
sys.path.insert(0, {str(TESTS)!r})
import sidar_torch
from sidar_torch.render import RenderSettings, SceneRenderer
from sidar_torch.scene import sample_sequence
from conftest import SMALL, small_config, textured_painting
seq = sample_sequence(small_config("ambient", n_views=1), np.random.default_rng(0))
painting = textured_painting(SMALL)
first, second = SceneRenderer(RenderSettings(SMALL)), SceneRenderer(RenderSettings(SMALL))
expected = first.render(seq, painting)
first.close()
again = second.render(seq, painting)
assert np.array_equal(again.views, expected.views)
third = SceneRenderer(RenderSettings(SMALL))
assert np.array_equal(third.render(seq, painting).views, expected.views)
"""
    skip_unless_egl_opens(run_on("egl", code))


FORK_AFTER_EGL = f"""
import sys
sys.path.insert(0, {str(TESTS)!r})
from torch.utils.data import DataLoader
from sidar_torch import SidarDataset, load_config
from sidar_torch.render import render_in_this_process
render_in_this_process()
config = load_config("misaligned", image_size=(24, 32), n_views=2)
SidarDataset(config=config).sample(0)  # an EGL context in this process
try:
    next(iter(DataLoader(SidarDataset(config=config, length=2), num_workers=1, timeout=120)))
except RuntimeError as error:
    assert "was forked from process" in str(error) and "forkserver" in str(error), error
else:
    raise AssertionError("a worker forked after its parent opened an EGL context rendered")
loader = DataLoader(SidarDataset(config=config, length=2), batch_size=2, num_workers=1, timeout=120,
                    multiprocessing_context="forkserver")
assert tuple(next(iter(loader))["images"].shape) == (2, 2, 3, 24, 32)
"""
"""Renders on EGL in this process, then asks a forked DataLoader worker and a forkserver one for a sample."""


def test_a_worker_forked_after_an_egl_render_is_refused_and_forkserver_workers_deliver():
    # EGL does not survive a fork: a child of a process that opened an EGL context hung at its first draw
    # (Mesa) or aborted (NVIDIA's driver). It is told so instead, and what to do.
    skip_unless_egl_opens(run_on("egl", FORK_AFTER_EGL, MESA_SHADER_CACHE_DISABLE="true"))


REFUSE_TO_LOAD = """
import ctypes
load = ctypes.CDLL.__init__
def refuse(self, name, *args, **kwargs):  # as if the library's files were not installed
    if name and any(f"lib{{library}}.so" in str(name) for library in {libraries!r}):
        raise OSError(f"{{name}}: cannot open shared object file: No such file or directory")
    return load(self, name, *args, **kwargs)
ctypes.CDLL.__init__ = refuse
"""
"""Makes every later ``ctypes`` load of the named libraries (``libX.so*``) fail, as when missing."""

OSMESA_HINT = "it needs OSMesa (Debian/Ubuntu: apt-get install libosmesa6)"
EGL_HINT = "it needs EGL (Debian/Ubuntu: apt-get install libegl1 libgl1-mesa-dri libopengl0)"


def test_a_missing_library_says_what_to_install_on_a_datasets_default_path_too():
    # A dataset in a process that may fork renders in a render process; the process itself checks the
    # libraries before it starts one (it failed in an import of PyOpenGL before, with an AttributeError).
    code = REFUSE_TO_LOAD.format(libraries=["OSMesa"]) + (
        "from sidar_torch import SidarDataset, load_config\n"
        "SidarDataset(config=load_config('misaligned', image_size=(24, 32), n_views=2)).sample(0)\n")
    result = run_on("osmesa", code)
    assert result.returncode != 0
    assert (f"RuntimeError: cannot open an offscreen OpenGL context on platform 'osmesa' (PyOpenGL cannot load "
            f"libOSMesa); {OSMESA_HINT}") in result.stderr, result.stderr[-2000:]


@pytest.mark.parametrize("platform, missing, env, expected", [
    ("osmesa", ["OSMesa"], {}, f"RuntimeError: cannot open an offscreen OpenGL context on platform 'osmesa' "
                                f"(PyOpenGL cannot load libOSMesa); {OSMESA_HINT}"),
    ("egl", ["EGL"], {}, f"(PyOpenGL cannot load libEGL); {EGL_HINT}"),
    ("egl", ["OpenGL", "GL"], {}, f"(PyOpenGL cannot load libOpenGL or libGL); {EGL_HINT}"),
    # glvnd's libEGL loads but finds no vendor library: as if libegl-mesa0 were missing.
    ("egl", [], {"__EGL_VENDOR_LIBRARY_FILENAMES": "/nonexistent/egl_vendor.json"},
     f"(OSError('EGL lists no device')); {EGL_HINT}"),
    ("egl", [], {"EGL_DEVICE_ID": "99"}, "ValueError: EGL_DEVICE_ID='99': expected a device number from 0 to"),
])
def test_a_missing_library_or_driver_says_what_to_install(platform, missing, env, expected):
    code = REFUSE_TO_LOAD.format(libraries=missing) + ("from sidar_torch.render import RenderSettings, SceneRenderer\n"
                                                    "SceneRenderer(RenderSettings((8, 8)))\n")
    result = run_on(platform, code, **env)
    assert result.returncode != 0
    assert expected in result.stderr, result.stderr[-1000:]


class OSMesaOwnBuffer:
    """Stand-in for ``framebuffer.Framebuffer`` that draws as pyrender does by default: upright,
    into OSMesa's own buffer (framebuffer 0), read from its front buffer bottom row first."""

    def __init__(self, height, width):
        self.height, self.width = height, width

    def multisampled(self):  # one sample per pixel, as the test's settings ask
        return contextlib.nullcontext()

    def resize(self, width, height):  # OSMesa's buffer is the context's own, of one size
        assert (height, width) == (self.height, self.width)

    def clear(self, bits):
        GL.glClear(bits)

    def begin_drawing(self, outputs=1):
        assert outputs == 1  # OSMesa's buffer has one colour output
        GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, 0)

    def end_drawing(self):
        GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, 0)
        GL.glReadBuffer(GL.GL_FRONT)
        GL.glPixelStorei(GL.GL_PACK_ALIGNMENT, 1)
        pixels = GL.glReadPixels(0, 0, self.width, self.height, GL.GL_RGBA, GL.GL_UNSIGNED_BYTE)
        return np.frombuffer(pixels, np.uint8).reshape(1, self.height, self.width, 4)[:, ::-1].copy()


@pytest.mark.skipif(GL_PLATFORM != "osmesa", reason="framebuffer 0 exists on OSMesa only")
def test_own_framebuffer_gives_the_pixels_of_osmesas_buffer(monkeypatch):
    # The renderer draws upside down into its framebuffer, as Mesa draws into OSMesa's buffer;
    # drawn upright, lit pixels round differently.
    sequences = [(sample_sequence(small_config(p), np.random.default_rng(s)), textured_painting(SMALL, s))
                 for p, s in SEQUENCES]
    settings = {replace(RenderSettings.from_config(small_config(p)), antialias=1, highlight_spill=True,
                        light_radius=0.0, texture_filter="trilinear") for p, _ in SEQUENCES}
    # the presets' renderer, at one sample per pixel, spilling highlights, hard shadows, trilinear texture
    assert len(settings) == 1
    # The painting seen in mirrors and glass (settings.mirrors) takes its texture level from screen-space
    # derivatives, which llvmpipe takes per 2 x 2 quad from one of its rows: drawn the other way up, a few
    # of those pixels move by a level (2 of 36864 view values in paper_misaligned's scene). Without
    # mirrors every byte is the same.
    for mirrors in (False, True):
        plain = replace(*settings, mirrors=mirrors)
        ours = SceneRenderer(plain)
        theirs = SceneRenderer(replace(plain, masks_from_stencil=False))  # OSMesa's buffer has no stencil
        theirs._passes.target = OSMesaOwnBuffer(*SMALL)
        for seq, painting in sequences:
            expected = ours.render(seq, painting)
            with monkeypatch.context() as patch:
                patch.setattr(passes, "FLIP_Y", np.eye(4))
                got = theirs.render(seq, painting)
            for name in ("masks", "label") if mirrors else ("views", "masks", "label"):
                assert np.array_equal(getattr(got, name), getattr(expected, name)), (name, mirrors)
            difference = np.abs(got.views.astype(int) - expected.views)
            assert difference.max() <= 1 and (difference > 0).mean() < 1e-3, (difference.max(), (difference > 0).sum())
        ours.close()
        theirs.close()
