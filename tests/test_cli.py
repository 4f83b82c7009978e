"""The command line's handling of what users type (issue 20 item 6, issue 25 item 4): tuples in
parentheses, "did you mean" for presets, one line and exit code 2 for every user mistake, and a
quiet stop when the reader of the output goes away."""

import os
import re
import subprocess
import sys
import time
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
    # Found only when a scene is drawn, in the warm-up (no camera meets the guarantee): still one line.
    pytest.param(["--set", "min_coverage=0.99", "--set", "fov_deg=(100, 100.4)"], "config fields 'min_coverage'",
                 marks=pytest.mark.gl),
], ids=["overflow", "unhashable", "deep", "area-light", "n-views", "memory", "preset", "guarantee"])
def test_user_mistakes_print_one_line_naming_the_field_and_exit_2(argv, message, capsys):
    assert message in _one_line_error(argv, capsys)


def test_an_output_path_that_cannot_be_made_is_one_line_before_rendering(tmp_path, capsys):
    (tmp_path / "file").write_text("x")
    assert "--out '" in _one_line_error(["--out", str(tmp_path / "file" / "sheet.png")], capsys)


def test_a_genuine_bug_keeps_its_traceback(monkeypatch):
    def broken(index):
        raise KeyError("a bug")

    monkeypatch.setattr(cli.SidarDataset, "warm_up", lambda self: None)
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


def test_a_misspelt_command_gets_a_did_you_mean(capsys):
    """Issue 34 item 7: ``preveiw`` gave argparse's "invalid choice" without a suggestion."""
    with pytest.raises(SystemExit) as exit_info:
        cli.main(["preveiw", "--samples", "1"])
    assert exit_info.value.code == 2
    assert "unknown command 'preveiw' (did you mean 'preview'?)" in capsys.readouterr().err


@pytest.mark.parametrize("count, noun, text", [(0, "sample", "0 samples"), (1, "sample", "1 sample"),
                                               (2, "view", "2 views")])
def test_counts_are_pluralised(count, noun, text):
    assert cli.counted(count, noun) == text


@pytest.mark.gl
def test_preview_prints_one_sample_and_the_wall_time_from_the_process_start_in_parts(tmp_path):
    """Issue 34 item 7: "1 samples of 1 views", and the time printed left out the start-up and counted the
    warm-up as rendering. Now the last line is the wall time since the process started, with the
    start-up, set-up, warm-up and rendering apart, and it cannot exceed the time measured from here."""
    begin = time.perf_counter()
    result = subprocess.run([sys.executable, "-m", "sidar_torch", "preview", "--samples", "1", *TINY, "--set", "n_views=1",
                             "--out", str(tmp_path / "sheet.png")], capture_output=True, text=True,
                            timeout=300, cwd=tmp_path, env={**os.environ, "PYTHONPATH": str(ROOT)})
    measured = time.perf_counter() - begin
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert "(1 sample of 1 view at 16x16" in lines[0], lines
    match = re.fullmatch(r"wall time ([\d.]+) s since the process started: start-up ([\d.]+) s, set-up ([\d.]+) s, "
                         r"warm-up ([\d.]+) s, rendering ([\d.]+) s, writing ([\d.]+) s, other (-?[\d.]+) s", lines[-1])
    assert match, lines[-1]
    total, start_up, *parts = (float(x) for x in match.groups())
    assert start_up > 0.1 and total <= measured + 0.1, (lines[-1], measured)  # importing torch takes time
    assert abs(total - start_up - sum(parts)) <= 0.25, lines[-1]  # the parts add up (0.05 s rounding each)


def test_export_refuses_a_count_below_one_before_any_work(capsys, monkeypatch):
    monkeypatch.setattr(cli.SidarDataset, "warm_up", lambda self: pytest.fail("warmed up before checking --count"))
    with pytest.raises(SystemExit):
        cli.main(["export", "--out", "unused", "--count", "0"])
    assert "count: expected an integer >= 1, got 0" in capsys.readouterr().err
