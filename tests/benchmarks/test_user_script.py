"""``python -m benchmarks.user_script``, shortened: a plain process's DataLoader figures and kornia's, printed as JSON."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = [pytest.mark.gl, pytest.mark.slow]  # renders in DataLoader workers

ROOT = Path(__file__).resolve().parents[2]


def test_the_user_script_prints_first_samples_throughput_and_kornia(tmp_path):
    out = tmp_path / "user.json"
    done = subprocess.run([sys.executable, "-m", "benchmarks.user_script", "--size", "24x32", "--samples", "2",
                           "--skip", "1", "--json", str(out)], capture_output=True, text=True, timeout=600, cwd=ROOT)
    assert done.returncode == 0, done.stderr
    figures = json.loads(out.read_text())
    assert json.loads(done.stdout) == figures
    assert set(figures["first_sample_s"]) == set(figures["samples_per_s"]) == {"1", "2"}
    assert all(value > 0 for value in (*figures["first_sample_s"].values(), *figures["samples_per_s"].values()))
    rates = figures["samples_per_s"]
    assert figures["worker_scaling"] == pytest.approx(rates["2"] / rates["1"])
    assert figures["kornia_ratio_1_worker"] == pytest.approx(figures["ms_per_view_1_worker"] / figures["kornia_ms_per_image"])
    assert figures["mesa_disk_cache_in_workers"] in ("on", "off") and "load average" in figures["machine"]
