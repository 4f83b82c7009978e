"""The command line's handling of what users type (issue 20 item 6, issue 25 item 4): tuples in
parentheses, "did you mean" for presets, one line and exit code 2 for every user mistake, and a
quiet stop when the reader of the output goes away."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

from sidar_torch import cli, load_config

ROOT = Path(__file__).resolve().parent.parent


@pytest.mark.parametrize("item, expected", [
    ("image_size=(192, 256)", {"image_size": [192, 256]}),
    ("image_size= ( 192,256 ) ", {"image_size": [192, 256]}),
    ("image_size=[192, 256]", {"image_size": [192, 256]}),
    ("light_types=(spot, point)", {"light_types": ["spot", "point"]}),
    ("n_views=3", {"n_views": 3}),
])
def test_set_reads_a_tuple_in_parentheses_like_a_list(item, expected):
    assert cli.parse_overrides([item]) == expected
    config = load_config("misaligned", **cli.parse_overrides([item]))
    for key, value in expected.items():
        assert getattr(config, key) == (tuple(value) if isinstance(value, list) else value)


def _one_line_error(argv, capsys) -> str:
    """The message ``sidar_torch preview`` prints for ``argv``, checked to be one line with exit code 2."""
    with pytest.raises(SystemExit) as exit_info:
        cli.main(["preview", *argv])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith("sidar_torch preview: ") and err.count("\n") == 1 and "Traceback" not in err, err
    return err


@pytest.mark.parametrize("argv, message", [
    (["--set", "camera_xy=1" + "0" * 400], "config field 'camera_xy': expected a finite number"),  # OverflowError
    (["--set", "light_types=[[spot]]"], "config field 'light_types': expected a list of words"),  # unhashable type
    (["--set", "image_size=" + "[" * 5000 + "]" * 5000], "nested too deeply"),  # RecursionError
    (["--set", "area_light_size=1e300"], "config field 'area_light_size': expected 0.0001 <= value <= 100"),
    (["--set", "n_views=" + "9" * 127], "config field 'n_views': expected 1 <= value <= 256"),
    (["--set", "image_size=(16384, 16384)"], "config fields 'image_size', 'n_views'"),
    (["--config", "misalinged"], "not a preset (did you mean 'misaligned'"),
    # Found only when a sample is drawn (no camera meets the guarantee): still one line.
    (["--set", "min_coverage=0.99", "--set", "fov_deg=(100, 100.4)"], "config fields 'min_coverage'"),
], ids=["overflow", "unhashable", "deep", "area-light", "n-views", "memory", "preset", "guarantee"])
def test_user_mistakes_print_one_line_naming_the_field_and_exit_2(argv, message, capsys):
    assert message in _one_line_error(argv, capsys)


def test_an_output_path_that_cannot_be_made_is_one_line_before_rendering(tmp_path, capsys):
    (tmp_path / "file").write_text("x")
    assert "--out '" in _one_line_error(["--out", str(tmp_path / "file" / "sheet.png")], capsys)


def test_a_genuine_bug_keeps_its_traceback(monkeypatch):
    def broken(index):
        raise KeyError("a bug")

    monkeypatch.setattr(cli.SidarDataset, "sample", lambda self, index: broken(index))
    with pytest.raises(KeyError, match="a bug"):
        cli.main(["preview", "--samples", "1"])


def _run_into_closed_pipe(argv: list[str], cwd: Path) -> subprocess.CompletedProcess:
    """Run ``python -m sidar_torch argv`` with stdout a pipe whose reading end is already closed."""
    read, write = os.pipe()
    os.close(read)
    try:
        return subprocess.run([sys.executable, "-m", "sidar_torch", *argv], stdout=write, stderr=subprocess.PIPE,
                              text=True, timeout=120, cwd=cwd, env={**os.environ, "PYTHONPATH": str(ROOT)})
    finally:
        os.close(write)


TINY = ["--set", "image_size=[16,16]", "--set", "n_views=2", "--set", "shadow_map_size=16"]


@pytest.mark.parametrize("argv", [
    pytest.param(["schema"], id="schema"),
    pytest.param(["preview", "--samples", "1", *TINY], id="preview", marks=pytest.mark.gl),
])  # export prints through the same main (a third subprocess would add about 10 s)
def test_a_closed_output_pipe_stops_every_command_quietly(argv, tmp_path):
    """``python -m sidar_torch schema | head`` raised BrokenPipeError: now no traceback, no
    "Exception ignored" at exit, and the exit code a process ended by SIGPIPE gives. The reading end
    is closed before the command starts, so the first write fails whatever the pipe's buffer holds."""
    result = _run_into_closed_pipe(argv, tmp_path)
    assert result.stderr == "" and result.returncode == cli.PIPE_CLOSED_EXIT == 141, result
