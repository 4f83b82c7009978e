"""``benchmarks.setting_cost`` (over ``benchmarks.paired``: a setting, a switch or an output compared two
ways), the former commands that run it, and ``revision_cost``, on tiny settings: what they print and
that a wrong field or override is named, never speed."""

import numpy as np
import pytest

from benchmarks import setting_cost

pytestmark = pytest.mark.gl  # renders


def test_a_switch_is_drawn_off_and_on_with_its_note(capsys):
    setting_cost.main(["--field", "mirrors", "--size", "24x32", "--samples", "2", "--set", "occluder_materials=[metallic]",
                       "--set", "n_occluders=[1,1]", "--set", "n_views=2"])
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("mirrors: ") and out[0].endswith("renderer: off: mirrors=False; on: mirrors=True")
    assert out[1].startswith("wall: median ms / view off") and out[2].startswith(" cpu: median ms / view off")
    assert out[3] == "4 of 4 views have a reflective or glass occluder"
    assert out[4].startswith("views: on against off: PSNR ")


def test_an_output_is_drawn_without_and_with_and_its_steps_are_timed(capsys):
    setting_cost.main(["--field", "opacities", "--size", "24x32", "--samples", "2"])
    out = capsys.readouterr().out.splitlines()
    assert out[0].endswith("renderer: without: outputs=[]; with: outputs=['opacities']")
    assert [line.split(":")[0].strip() for line in out[1:]] == ["wall", "cpu", "opacity (wall)", "views"]


def test_a_field_that_is_not_a_switch_wants_two_values_and_a_wrong_override_is_named():
    with pytest.raises(SystemExit, match=r"shadow_map_size: not a RenderSettings switch .* \(--values A B\)"):
        setting_cost.main(["--field", "shadow_map_size", "--samples", "1"])
    with pytest.raises(SystemExit, match="occluder_materials"):
        setting_cost.main(["--field", "mirrors", "--set", "occluder_materials=[chrome]", "--samples", "1"])


def test_a_skip_prints_the_lookups_kept_and_leaves_the_views_the_same(capsys):
    setting_cost.main(["--field", "split_shadow_lookups", "--size", "96x128", "--samples", "2", "--set", "n_views=2",
                       "--set", "n_occluders=[2,2]"])
    out = capsys.readouterr().out.splitlines()
    share = int(out[3].split("keeps ")[1].split(" %")[0])
    assert 0 < share < 100  # a split happened and kept some lookups
    assert out[4].startswith("views: on against off: PSNR inf (the same bytes)")


def test_setting_cost_prints_what_each_value_gives_the_renderer(capsys):
    setting_cost.main(["--field", "shadow_map_size", "--values", "1024", "auto", "--size", "48x64", "--samples", "2",
                       "--set", "n_views=2"])
    out = capsys.readouterr().out.splitlines()
    assert out[0].endswith("renderer: 1024: shadow_map_size=1024; auto: shadow_map_size=512")
    assert out[1].startswith("wall: median ms / view 1024 ") and ", auto " in out[1]
    assert out[3].startswith("views: auto against 1024: PSNR ") and "of 4 views the same bytes" in out[3]
    with pytest.raises(SystemExit, match="same settings"):
        setting_cost.main(["--field", "n_lights", "--values", "[1,2]", "[2,3]", "--samples", "1"])


def test_setting_cost_compares_a_renderer_field_that_no_config_field_sets(capsys):
    setting_cost.main(["--field", "footprint_tile", "--values", "32", "8", "--size", "96x128", "--samples", "2",
                       "--set", "n_views=2", "--set", "n_occluders=[2,2]"])
    out = capsys.readouterr().out.splitlines()
    assert out[0].endswith("renderer: 32: footprint_tile=32; 8: footprint_tile=8")
    assert out[3].startswith("views: 8 against 32: PSNR inf (the same bytes); 4 of 4 views the same bytes")
    with pytest.raises(SystemExit, match="footprint_tile: expected an integer"):
        setting_cost.main(["--field", "footprint_tile", "--values", "16", "0", "--samples", "1"])
    with pytest.raises(SystemExit, match="tile_size"):
        setting_cost.main(["--field", "tile_size", "--values", "16", "8", "--samples", "1"])


def test_the_view_difference_line_tells_the_same_bytes_from_a_difference():
    same = [np.zeros((2, 4, 4, 3), np.int16)]
    assert setting_cost.view_difference(same, ("a", "b")) == (
        "views: b against a: PSNR inf (the same bytes); 2 of 2 views the same bytes; "
        "mean |difference| 0.000 levels, largest 0")
    one = np.zeros((2, 4, 4, 3), np.int16)
    one[1, 0, 0, 0] = -51  # mse 51^2 / 96: PSNR 10 log10(96 * 25)
    line = setting_cost.view_difference([one], ("a", "b"))
    assert f"PSNR {10 * np.log10(96 * 25):.2f} dB; 1 of 2 views the same bytes" in line and line.endswith("largest 51")


def test_clear_written_texels_prints_the_texels_cleared(capsys):
    from sidar_torch import load_config
    from sidar_torch.render import RenderSettings, shared_renderer
    from sidar_torch.scene import sample_sequence

    # Earlier work of the process's shared renderer (the skip on, as by default) does not count.
    config = load_config("misaligned", image_size=(48, 64), n_views=6, n_occluders=(3, 3))
    painting = np.zeros((48, 64, 3), np.uint8)
    for seed in range(8):  # 48 views: more clears than the measured run's, had they counted
        shared_renderer(RenderSettings.from_config(config)).render(sample_sequence(config, np.random.default_rng(seed)),
                                                                   painting)
    setting_cost.main(["--field", "clear_written_texels", "--size", "48x64", "--samples", "3", "--set", "n_views=2",
                       "--set", "n_occluders=[2,3]"])
    out = capsys.readouterr().out.splitlines()
    depth = int(out[3].split(" %")[0])
    assert 0 < depth < 100 and out[0].startswith("clear_written_texels: ")


def test_revision_cost_runs_each_tree_in_its_own_process_and_prints_the_ratio(capsys, tmp_path):
    from pathlib import Path

    from benchmarks import revision_cost

    root = str(Path(revision_cost.__file__).resolve().parents[1])
    revision_cost.main(["--trees", root, root, "--size", "24x32", "--samples", "1", "--rounds", "1"])
    out = capsys.readouterr().out.splitlines()
    assert out[1].startswith(f"round 1 A {root}: median") and out[2].startswith(f"round 1 B {root}: median")
    assert out[3].startswith("median total: A ") and "B / A = " in out[3]
    with pytest.raises(SystemExit, match="holds no sidar_torch package"):
        revision_cost.main(["--trees", root, str(tmp_path)])


def test_revision_cost_sets_a_sides_environment_in_its_processes_only(capsys):
    from pathlib import Path

    from benchmarks import revision_cost

    root = str(Path(revision_cost.__file__).resolve().parents[1])
    common = ["--trees", root, root, "--size", "24x32", "--samples", "1", "--rounds", "1"]
    revision_cost.main([*common, "--env-b", "PYOPENGL_ERROR_CHECKING=0"])
    assert capsys.readouterr().out.splitlines()[2].startswith(f"round 1 B {root} PYOPENGL_ERROR_CHECKING=0: median")
    with pytest.raises(SystemExit, match="the process for"):  # a platform PyOpenGL has not: B's process fails
        revision_cost.main([*common, "--env-b", "PYOPENGL_PLATFORM=no-such-platform"])
    with pytest.raises(SystemExit):
        revision_cost.main([*common, "--env-a", "NO_EQUALS_SIGN"])
