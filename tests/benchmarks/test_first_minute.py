"""``python -m benchmarks.first_minute``, shortened: fresh interpreters' first samples, cold and warm cache."""

import subprocess
import sys
from pathlib import Path

import pytest

from benchmarks.first_minute import FIGURES

pytestmark = [pytest.mark.gl, pytest.mark.slow]  # renders, in fresh interpreters

ROOT = Path(__file__).resolve().parents[2]


def test_first_minute_prints_every_figure_cold_and_warm():
    done = subprocess.run([sys.executable, "-m", "benchmarks.first_minute", "--size", "24x32", "--runs", "1"],
                          capture_output=True, text=True, timeout=600, cwd=ROOT)
    assert done.returncode == 0, done.stderr[-3000:]
    lines = done.stdout.splitlines()
    rows = {line.split()[0]: line.split() for line in lines[1:1 + len(FIGURES)]}
    assert list(rows) == list(FIGURES), lines
    for name, row in rows.items():
        cold, warm = float(row[2]), float(row[4])
        assert cold > 0 and warm > 0, row
    assert float(rows["to_first"][2]) >= float(rows["first"][2])  # import + dataset + first
    assert "load average" in lines[-1]
