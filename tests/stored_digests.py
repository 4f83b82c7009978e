"""Stored SHA-256 digests of a few samples of every preset: a guard that a refactor changes no byte.

``python tests/stored_digests.py --write`` records them (run it only in a commit whose purpose is to
change samples, and say so in the commit message); ``tests/test_stored_digests.py`` compares.

Pixels come from the rasteriser, so they are compared only where the GL renderer string (which
names llvmpipe's LLVM version and vector width) is the one the digests were recorded on; the
geometry (homographies, cameras) and the sample's keys, shapes and dtypes are compared everywhere.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from conftest import sample_digest  # noqa: E402

STORE = HERE / "data" / "sample_digests.json"
SIZE = (48, 64)
N_VIEWS = 3
INDICES = (0, 1)
SEED = 3
PIXEL_KEYS = ("images", "masks", "opacities", "label")
EVERYTHING_ON = dict(opacity_output=True, background="view", exposure_jitter=True, sensor_noise=True, jpeg=True,
                     mesh_detail="auto", n_occluders=(3, 3))
"""Overrides of the extra ``misaligned+everything`` entry: the optional outputs and view effects."""


def gl_renderer() -> str:
    """The GL renderer string of this process's shared renderer's context (e.g. llvmpipe's)."""
    from OpenGL import GL

    return GL.glGetString(GL.GL_RENDERER).decode()


def current_digests() -> dict[str, dict[str, str]]:
    """``{"name/index": {key: sha256}}`` for every preset (and ``misaligned+everything``) and ``INDICES`` at ``SIZE``."""
    from sidar_torch import SidarDataset, available_presets, load_config

    configs = {preset: load_config(preset, image_size=SIZE, n_views=N_VIEWS) for preset in available_presets()}
    configs["misaligned+everything"] = configs["misaligned"].replace(**EVERYTHING_ON)
    return {f"{name}/{index}": sample_digest(SidarDataset(None, config, seed=SEED).sample(index))
            for name, config in configs.items() for index in INDICES}


if __name__ == "__main__":
    if sys.argv[1:] != ["--write"]:
        raise SystemExit("usage: python tests/stored_digests.py --write")
    digests = current_digests()
    STORE.write_text(json.dumps({"gl_renderer": gl_renderer(), "samples": digests}, indent=1, sort_keys=True) + "\n")
    print(f"wrote {STORE} ({len(digests)} samples)")
