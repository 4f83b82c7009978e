"""``benchmarks.depth_flow`` on tiny settings: what it prints, never speed."""

import pytest

from benchmarks import depth_flow

pytestmark = pytest.mark.gl  # renders


def test_depth_flow_prints_the_depths_error_and_flows_cost_per_thread_count(capsys):
    depth_flow.main(["--size", "24x32", "--samples", "1", "--repeats", "1", "--set", "n_views=2"])
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("depth_flow: parallax n_views=2 24x32 (H x W), 1 sequences x 2 views")
    error = float(out[1].split("max ")[1].split(" ")[0])
    assert out[1].startswith("depth on the painting: largest relative error per view") and 0 <= error < 1e-4
    assert out[2].startswith("flow(sample, i, 0), 1 thread: median") and out[3].startswith("flow(sample, i, 0), 2 threads")
    assert "load average" in out[4]


def test_depth_flow_names_a_wrong_override():
    with pytest.raises(SystemExit, match="n_views"):
        depth_flow.main(["--set", "n_views=0", "--samples", "1"])
