"""``benchmarks/ray_throughput.py`` on tiny settings: its figures exist and agree with each other, never speed."""

import pytest

pytestmark = pytest.mark.gl  # renders


@pytest.mark.slow
def test_figures_are_consistent(capsys):
    pytest.importorskip("ray")
    from benchmarks import ray_throughput

    ray_throughput.main(["--size", "24x32", "--views", "2", "--count", "4", "--repeats", "1"])
    printed = capsys.readouterr().out
    rows = [line for line in printed.splitlines() if line.startswith("| ") and not line.startswith("| way")]
    assert [row.split(" | ")[0] for row in rows] == ["| one process", "| DataLoader, 2 workers", "| Ray, 1 actor",
                                                     "| Ray, 2 actors"]
    assert rows[0].split(" | ")[3] == "1.00"  # the baseline's ratio to itself
    with pytest.raises(ValueError, match="count"):
        ray_throughput.measure("misaligned", (24, 32), 2, count=3, repeats=1)
