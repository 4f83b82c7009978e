"""``benchmarks.lens_cost`` on tiny settings: what it prints, never speed."""

import pytest

from benchmarks import lens_cost

pytestmark = pytest.mark.gl  # renders


def test_lens_cost_prints_a_row_per_model_and_the_load(capsys):
    lens_cost.main(["--size", "24x32", "--samples", "2", "--set", "n_views=2"])
    out = capsys.readouterr().out.splitlines()
    assert [line.split("|")[1].strip() for line in out[3:6]] == list(lens_cost.MODELS)
    assert out[3].split("|")[4].strip() == "1.00" and "load average" in out[6]


def test_lens_cost_names_a_wrong_override():
    with pytest.raises(SystemExit, match="lens_k1"):
        lens_cost.main(["--set", "lens_k1=[-0.9,0]", "--samples", "1"])
