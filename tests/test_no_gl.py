"""Without the GL libraries: ``import sidar_torch``, configs, ``homography_pairs`` and reading an
exported set work, and load neither pyrender nor PyOpenGL; the first render raises the error that
says what to install.

The child process refuses to load every GL library through ``ctypes`` (how PyOpenGL loads them),
as on a machine where none is installed (``test_platform`` simulates single missing libraries
the same way).
"""

import os
import subprocess
import sys

from sidar_torch import SidarDataset, export_dataset

from conftest import small_config
import pytest

pytestmark = pytest.mark.gl  # writes the export it reads; the no-GL part runs in a subprocess

GL_LIBRARIES = ["OSMesa", "GL", "EGL", "OpenGL", "GLX", "GLESv1_CM", "GLESv2"]

NO_GL = f"""
import ctypes, sys
load = ctypes.CDLL.__init__
def refuse(self, name, *args, **kwargs):  # as if no GL library were installed
    if name and any(f"lib{{library}}.so" in str(name) for library in {GL_LIBRARIES!r}):
        raise OSError(f"{{name}}: cannot open shared object file: No such file or directory")
    return load(self, name, *args, **kwargs)
ctypes.CDLL.__init__ = refuse

import torch
import sidar_torch
from sidar_torch import ExportedDataset, SidarConfig, SidarDataset, available_presets, homography_pairs, load_config

configs = [load_config(name) for name in available_presets()] + [SidarConfig(n_views=3)]
exported = ExportedDataset(sys.argv[1])
pairs = homography_pairs(exported[0], 16, generator=torch.Generator().manual_seed(0))
assert pairs["patch_a"].shape[-2:] == (16, 16), pairs["patch_a"].shape
loaded = sorted(m for m in sys.modules if m.split(".")[0] in ("pyrender", "OpenGL", "trimesh", "pyglet"))
assert not loaded, loaded
print("no GL loaded", flush=True)
SidarDataset(config=load_config(image_size=(8, 8), n_views=1)).sample(0)
"""


def test_config_pairs_and_reader_work_without_gl_and_the_first_render_says_what_to_install(tmp_path):
    config = small_config(n_views=2, image_size=(32, 48), n_lights=(0, 0), n_occluders=(0, 0))
    export_dataset(SidarDataset(config=config, seed=0), tmp_path / "set", count=1, progress=False)
    result = subprocess.run([sys.executable, "-c", NO_GL, str(tmp_path / "set")], capture_output=True, text=True,
                            timeout=300, env={**os.environ, "PYOPENGL_PLATFORM": "osmesa"})
    assert "no GL loaded" in result.stdout, result.stderr[-2000:]
    assert result.returncode != 0
    last = result.stderr.strip().splitlines()[-1]
    assert last.startswith("RuntimeError: cannot open an offscreen OpenGL context on platform 'osmesa'"), last
    assert "apt-get install libosmesa6" in last, last
