"""``benchmarks.shader_cost``: every cut still finds its text in our shaders, a stale cut is refused by
name, and a tiny run prints a row per cut (never speed)."""

import pytest

from benchmarks import shader_cost


@pytest.mark.parametrize("name", sorted(shader_cost.CUTS))
def test_every_cut_applies_to_the_shader_files(name):
    with shader_cost.cut_applied(shader_cost.CUTS[name][1]):
        pass  # raises if a replaced text is not in its file exactly once


def test_a_stale_cut_is_refused_naming_the_file_and_the_text():
    with pytest.raises(ValueError, match=r"surface\.frag holds the cut text 0 times, expected once: 'no such line'"):
        with shader_cost.cut_applied((("surface.frag", "no such line", ""),)):
            pass


def test_the_cut_is_made_in_the_block_only():
    from sidar_torch.render.programs import program_source

    original = program_source("surface.frag", {})
    with shader_cost.cut_applied(shader_cost.CUTS["encoding"][1]):
        cut = program_source("surface.frag", {})
    assert "return c;" in cut and "return c;" not in original
    assert program_source("surface.frag", {}) == original


@pytest.mark.gl
def test_a_tiny_run_prints_a_row_per_cut(capsys):
    medians = shader_cost.main(["--size", "24x32", "--samples", "1", "--rounds", "1", "--set", "n_views=2"])
    out = capsys.readouterr().out.splitlines()
    assert [line.split(" | ")[0].lstrip("| ") for line in out[3:3 + len(shader_cost.CUTS)]] == list(shader_cost.CUTS)
    assert set(medians) == set(shader_cost.CUTS) and all(value > 0 for value in medians.values())
    with pytest.raises(SystemExit, match="n_lightz"):
        shader_cost.main(["--set", "n_lightz=[1,1]", "--samples", "1"])
