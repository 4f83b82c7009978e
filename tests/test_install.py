"""A wheel installed outside the checkout loads every preset, renders, and runs ``preview``.

The wheel is built from a copy of the package's files (so the build leaves nothing in the
checkout) with ``pip wheel --no-deps --no-build-isolation``, then installed with ``--no-deps`` into
a fresh virtual environment in a temporary folder. That environment reuses this one's packages
(torch, pyrender, ...) through a ``.pth`` file naming this environment's site-packages: a plain
path line, so the ``.pth`` files there (this environment's editable install of ``sidar_torch``)
are not run, and the environment's own site-packages, holding the wheel, comes first on
``sys.path``. Everything runs from another working directory, and the test checks that the
``sidar_torch`` imported there is the wheel's.
"""

import json
import os
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path
import pytest

pytestmark = pytest.mark.gl  # renders

ROOT = Path(__file__).resolve().parent.parent

PACKAGE_FILES = ["pyproject.toml", "setup.cfg", "README.md", "sidar_torch"]
"""What a build reads: the metadata, the readme it names, the package."""

USE_THE_WHEEL = """
import json, sys
import sidar_torch
from sidar_torch import SidarDataset, available_presets, load_config
configs = {name: load_config(name).n_views for name in available_presets()}
sample = SidarDataset(config=load_config("misaligned", image_size=(24, 32), n_views=2), seed=0).sample(0)
print(json.dumps({"file": sidar_torch.__file__, "presets": configs, "images": list(sample["images"].shape)}))
"""


def run(*command, cwd, **kwargs):
    """Run ``command`` in ``cwd`` without PYTHONPATH; the finished process (raises on failure)."""
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    result = subprocess.run([str(c) for c in command], cwd=cwd, env=env, capture_output=True, text=True,
                            timeout=300, **kwargs)
    assert result.returncode == 0, f"{command}\n{result.stdout[-2000:]}\n{result.stderr[-3000:]}"
    return result


@pytest.mark.slow
def test_a_wheel_installed_elsewhere_loads_every_preset_renders_and_previews(tmp_path):
    source = tmp_path / "source"
    for name in PACKAGE_FILES:
        if (ROOT / name).is_dir():
            shutil.copytree(ROOT / name, source / name, ignore=shutil.ignore_patterns("__pycache__"))
        else:
            source.mkdir(exist_ok=True)
            shutil.copy(ROOT / name, source / name)
    run(sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "--no-index", "-q",
        "--wheel-dir", tmp_path / "wheels", source, cwd=tmp_path)
    (wheel,) = (tmp_path / "wheels").glob("sidar_torch-*.whl")

    env_dir = tmp_path / "env"
    run(sys.executable, "-m", "venv", "--without-pip", env_dir, cwd=tmp_path)
    python = env_dir / "bin" / "python"
    site = Path(run(python, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])",
                    cwd=tmp_path).stdout.strip())
    ours = dict.fromkeys([sysconfig.get_paths()["purelib"], sysconfig.get_paths()["platlib"]])
    (site / "reuse_test_environment.pth").write_text("".join(f"{path}\n" for path in ours))
    run(python, "-m", "pip", "install", "--no-deps", "--no-index", "-q", wheel, cwd=tmp_path)

    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    used = json.loads(run(python, "-c", USE_THE_WHEEL, cwd=elsewhere).stdout)
    assert Path(used["file"]).is_relative_to(site), f"imported {used['file']}, not the wheel in {site}"
    assert set(used["presets"]) >= {"misaligned", "aligned", "ambient", "paper_misaligned"}, used["presets"]
    assert used["images"] == [2, 3, 24, 32]

    run(python, "-m", "sidar_torch", "preview", "--samples", "1", "--set", "image_size=[24,32]",
        "--set", "n_views=2", "--out", "sheet.png", cwd=elsewhere)
    assert (elsewhere / "sheet.png").stat().st_size > 0
