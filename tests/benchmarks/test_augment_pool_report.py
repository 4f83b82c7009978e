"""``benchmarks/augment_pool.py`` on tiny settings: its figures exist and agree with each other, never speed."""

import pytest

from benchmarks import augment_pool

pytestmark = pytest.mark.gl  # renders


@pytest.mark.slow
def test_figures_are_consistent(capsys):
    augment_pool.main(["--batch", "2", "--size", "48x64", "--calls", "1"])
    printed = capsys.readouterr().out
    assert "pool speedup (wall, num_workers=2 over 0)" in printed and "own cost, CPU per image" in printed
    f = augment_pool.measure("misaligned", 2, 2, (48, 64), workers=2, calls=1)
    assert all(value > 0 for value in f.values()), f
    assert f["pool_speedup"] == pytest.approx(f["serial_wall"] / f["pool_wall"])
    assert f["pool_cpu_with_workers"] > f["pool_cpu"]  # the workers did the rendering
