"""Long runs, shortened for CI: ``python -m benchmarks.soak`` over 150 samples must keep memory, shader
programs and GL objects flat once warm (the long soaks: docs/speed.md, "Memory over long runs")."""

import json
import subprocess
import sys
from pathlib import Path
import pytest

pytestmark = pytest.mark.gl  # renders

ROOT = Path(__file__).resolve().parents[2]

MAX_GROWTH_MB = 10
"""Allowed resident-memory growth over the 100 samples after the warm-up (measured: under 1 MiB;
the leak this guards against, one set of shader programs per render, costs about 4 MB a sample)."""


def run_soak(tmp_path, n_views, *options):
    """``python -m benchmarks.soak`` on ``misaligned`` with ``n_views`` views at 48x64 (shadow maps of
    256 texels) and ``options``: the finished process and its JSON summary (its last line)."""
    config = tmp_path / "soak.yaml"
    config.write_text(f"base: misaligned\nn_views: {n_views}\nshadow_map_size: 256\n")
    done = subprocess.run([sys.executable, "-m", "benchmarks.soak", "--config", str(config), "--size", "48x64",
                           *options], capture_output=True, text=True, timeout=600, cwd=ROOT)
    assert done.returncode in (0, 1), done.stderr
    return done, json.loads(done.stdout.splitlines()[-1])


@pytest.mark.slow
def test_short_soak_keeps_memory_programs_and_gl_objects_flat(tmp_path):
    # The misaligned preset (lights, shadows, occluders; a new painting every sample) with 3 views
    # and small shadow maps to keep it short. The 150 samples cycle through 50 indices, so every
    # pool (meshes, lights, programs) is full after the 50-sample warm-up and GL counts must not move.
    done, summary = run_soak(tmp_path, 3, "--samples", "150", "--every", "25", "--warmup", "50", "--distinct", "50",
                             "--max-growth-mb", str(MAX_GROWTH_MB))
    after = [r for r in summary["reports"] if r["samples"] >= 50]
    assert len(after) == 5
    for key in ("programs", "gl_textures", "gl_buffers"):
        assert len({r[key] for r in after}) == 1, (key, summary["reports"])
    assert summary["growth_mb"] <= MAX_GROWTH_MB, summary["reports"]
    assert done.returncode == 0, done.stdout


@pytest.mark.slow
def test_a_soak_in_dataloader_workers_reports_each_workers_memory_heap_and_python_growth(tmp_path):
    # Issue 34 item 5: the growth was seen in DataLoader workers, so each worker reports its own figures:
    # resident memory, glibc's heap in use and free, the resident memory after malloc_trim, and (with
    # --tracemalloc) the source lines whose Python memory grew after the warm-up.
    done, summary = run_soak(tmp_path, 2, "--samples", "6", "--every", "2", "--warmup", "2", "--workers", "2",
                             "--trim", "--tracemalloc")
    reports = summary["reports"]
    assert sorted((r["worker"], r["samples"]) for r in reports) == [(w, s) for w in (0, 1) for s in (2, 4, 6)]
    for r in reports:
        assert 0 < r["heap_used_mb"] < r["rss_mb"] and r["heap_free_mb"] >= 0, r
        assert 0 < r["rss_trimmed_mb"] <= r["rss_mb"] + 1, r
    for worker in (0, 1):
        lines = done.stdout.splitlines()
        top = lines.index(next(line for line in lines if line.startswith(f"worker {worker}: growth after warm-up")))
        assert ".py:" in lines[top + 1] and "size=" in lines[top + 1], lines[top:top + 3]
