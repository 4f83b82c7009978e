"""The docs stay true: the Python snippets of the README and the pages run as written (dataset,
augmentation, pairs, torchrun), every shell command they show parses with the real argument parser
of its tool, every file they name exists, the configuration page's table is the generated schema,
and every relative link resolves."""

import argparse
import contextlib
import importlib
import importlib.util
import io
import os
import re
import shlex
import socket
import subprocess
import sys
from pathlib import Path
from unittest import mock

import pytest

ROOT = Path(__file__).resolve().parent.parent
README = ROOT / "README.md"
DOCS = ROOT / "docs"
SNIPPET_PAGES = (README, DOCS / "usage.md", DOCS / "distributed.md", DOCS / "ray.md")
"""Where the Python snippets are, in the order a reader meets them."""
COMMAND_PAGES = (README, *sorted(DOCS.glob("*.md")), ROOT / "benchmarks" / "README.md", ROOT / "configs" / "README.md")
"""Every page a user reads commands from."""


def python_blocks() -> list[str]:
    return [block for page in SNIPPET_PAGES
            for block in re.findall(r"^```python\n(.*?)^```", page.read_text(), flags=re.M | re.S)]


def run(code: str, env: dict | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600,
                          env={**os.environ, **(env or {})}, cwd=README.parent)


def test_every_snippet_is_checked_here():
    blocks = python_blocks()
    assert len(blocks) == 6
    assert "AugmentationSequential" in blocks[3] and "AugmentationSequential" not in "".join(blocks[:3])
    assert "torchrun" in blocks[4] and "torchrun" not in "".join(blocks[:4])
    assert "ray_dataset" in blocks[5] and "ray_dataset" not in "".join(blocks[:5])


@pytest.mark.slow
@pytest.mark.gl
def test_dataset_augmentation_and_pairs_snippets_run():
    blocks = python_blocks()
    # The pairs snippet continues the augmentation snippet; each runs as a user would paste it.
    code = blocks[0] + "\n" + blocks[1] + "\n" + blocks[2] + "\n" + "assert batch['images'].shape == (8, 6, 3, 384, 512)\n" \
        "assert out['images'].shape == (4, 3, 3, 192, 256)\nassert pairs['corner_offsets'].shape == (4, 4, 2)\n"
    result = run(code)
    assert result.returncode == 0, result.stderr[-2000:]


@pytest.mark.gl
def test_kornia_pipeline_snippet_runs():
    # issue 48: the AugmentationSequential example lived only in a docstring.
    code = python_blocks()[3] + (
        "\nassert out.shape == (4, 3, 192, 256) and step.last['applied'].shape == (4,)"
        "\nn = int(step.last['applied'].sum())"
        "\nassert step.last['homographies'][:, 0, 1].shape == (n, 3, 3) and step.last['images'].shape[:2] == (n, 2)\n")
    result = run(code)
    assert result.returncode == 0, result.stderr[-2000:]


README_WARP = re.compile(r"`(kornia\.geometry\.transform\.warp_perspective\(images\[i\][^`]*)`")
"""The README's inline call that warps view i onto view j."""


@pytest.mark.gl
def test_the_readmes_warp_of_view_i_lands_on_view_j():
    # issue 48: the README's warp_perspective(images[i], homographies[i, j], (H, W)) failed as written
    # (kornia warps batches). Its line, as written, run on a rendered sample.
    import kornia
    import torch

    from sidar_torch import SidarDataset, load_config

    (call,) = README_WARP.findall(README.read_text().replace("\n", " "))
    config = load_config("ambient", image_size=(96, 128), n_views=2, max_tilt_deg=40, fov_deg=(50, 70))
    sample = SidarDataset(config=config, seed=0).sample(0)
    (H, W), i, j = config.image_size, 0, 1
    names = {"kornia": kornia, "images": sample["images"], "homographies": sample["homographies"],
             "i": i, "j": j, "H": H, "W": W}
    warped = eval(call, names)
    assert warped.shape == sample["images"][j].shape, call
    seen = kornia.geometry.transform.warp_perspective(1 - sample["masks"][i][None], sample["homographies"][i, j][None],
                                                      (H, W), mode="nearest")[0] * (1 - sample["masks"][j])
    seen = -torch.nn.functional.max_pool2d(-seen[None], 7, stride=1, padding=3)[0]  # 3 px from any edge
    assert seen.sum() > 500
    error = ((warped - sample["images"][j]).abs() * seen).sum() / (3 * seen.sum())
    unwarped = ((sample["images"][i] - sample["images"][j]).abs() * seen).sum() / (3 * seen.sum())
    assert error < 0.02 and error < 0.5 * unwarped, (call, float(error), float(unwarped))


@pytest.mark.gl
def test_torchrun_snippet_runs_as_a_one_rank_job():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    env = {"RANK": "0", "WORLD_SIZE": "1", "LOCAL_RANK": "0", "MASTER_ADDR": "127.0.0.1", "MASTER_PORT": str(port)}
    code = python_blocks()[4] + "\nassert list(ds.indices())[:3] == [0, 1, 2]\ntorch.distributed.destroy_process_group()\n"
    result = run(code, env)
    assert result.returncode == 0, result.stderr[-2000:]


@pytest.mark.slow
@pytest.mark.gl
def test_ray_snippet_runs_on_a_local_cluster():
    pytest.importorskip("ray")
    code = python_blocks()[5] + "\nassert images.shape == (4, 6, 3, 192, 256)\nray.shutdown()\n"
    result = run(code)
    assert result.returncode == 0, result.stderr[-2000:]


def test_configuration_page_table_is_the_generated_schema():
    from sidar_torch.config.schema import schema_markdown

    text = (DOCS / "configuration.md").read_text()
    start = text.index("<!-- schema:")
    table = text[text.index("\n", start) + 1:text.index("<!-- end schema -->")].rstrip("\n")
    assert table == schema_markdown()


def test_every_config_field_has_a_meaning_in_the_schema():
    from sidar_torch.config.schema import schema_rows

    assert all(row["meaning"] for row in schema_rows()), [row["name"] for row in schema_rows() if not row["meaning"]]


def test_every_relative_link_of_the_docs_resolves():
    pages = [README, *sorted(DOCS.glob("*.md")), ROOT / "benchmarks" / "README.md", ROOT / "configs" / "README.md"]
    broken = []
    for page in pages:
        for target in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", page.read_text()):
            if "://" not in target and not (page.parent / target).exists():
                broken.append(f"{page.relative_to(ROOT)} -> {target}")
    assert not broken, broken


def test_readme_is_short_and_cites_nothing_outside_the_project():
    text = README.read_text()
    assert len(text.encode()) <= 15_000
    for page in [README, *DOCS.glob("*.md")]:
        assert "../shared" not in page.read_text() and "anchors/" not in page.read_text(), page.name


# Documented commands: every shell line of a ```bash (or ```sh) block, and every command of ours
# quoted inline (`python -m ...`, `sidar-torch ...`, `bash scripts/run.sh ...`, `python scripts/x.py ...`)
# is split as the shell would (shlex) and its arguments parsed by the tool's own argparse parser, which
# runs nothing. Other programs (pip, apt-get, torchrun) are not ours to check.

OURS = re.compile(r"(?:[A-Z_][A-Z0-9_]*=\S+\s+)*(?:nice\s+)?(?:\.venv/bin/)?"
                  r"(?:python3?\s+(?:-m\s+\w|\S+\.py\b)|sidar-torch\b|bash\s+scripts/run\.sh\b)")
"""The start of a command of this project (environment variables and ``nice`` may precede it)."""
OTHER_PROGRAMS = ("pip", "sudo", "apt-get", "torchrun")
"""First words of shell lines that run someone else's program: not checked."""
SHELL_BLOCK_LANGUAGES = ("bash", "sh", "shell", "console")
PROJECT_FOLDERS = ("tests", "examples", "configs", "scripts", "benchmarks", "sidar_torch")
"""A backticked path or an argument starting with one of these names a file of the repository."""


def _line_of(text: str, offset: int) -> int:
    return text.count("\n", 0, offset) + 1


def documented_commands() -> list[tuple[str, str, bool]]:
    """``(where, command, inline)`` for every command the pages show: ``where`` is ``page:line``;
    ``inline`` says it was quoted in prose (there a bare tool name, with no arguments, names the tool)."""
    found = []
    for page in COMMAND_PAGES:
        text, name = page.read_text(), page.relative_to(ROOT)
        fences = list(re.finditer(r"^```(\w*)\n(.*?)^```", text, flags=re.M | re.S))
        for fence in fences:
            body, first = fence.group(2), _line_of(text, fence.start(2))
            for n, line in enumerate(body.replace("\\\n", " ").split("\n")):
                line = line.strip()
                shell = fence.group(1) in SHELL_BLOCK_LANGUAGES
                if line and not line.startswith("#") and (shell or OURS.match(line)):
                    found.append((f"{name}:{first + n}", line, False))
        prose = re.sub(r"^```.*?^```", lambda m: "\n" * m.group(0).count("\n"), text, flags=re.M | re.S)
        for span in re.finditer(r"`([^`]+)`", prose):
            command = " ".join(span.group(1).split())
            if OURS.match(command):
                found.append((f"{name}:{_line_of(text, span.start())}", command, True))
    return found


def documented_paths() -> list[tuple[str, str]]:
    """``(where, path)`` for every backticked repository path of the pages and every path argument of
    their commands (``tests/x.py::test_y`` names ``tests/x.py``; placeholders like ``<preset>`` are skipped)."""
    paths = []
    for page in COMMAND_PAGES:
        text, name = page.read_text(), page.relative_to(ROOT)
        for span in re.finditer(r"`([^`\s]+)`", text):
            paths.append((f"{name}:{_line_of(text, span.start())}", span.group(1)))
    for where, command, _ in documented_commands():
        paths += [(where, word) for word in shlex.split(command, comments=True)]
    return [(where, path.split("::")[0]) for where, path in paths
            if path.split("/")[0] in PROJECT_FOLDERS and "/" in path and not re.search(r"[<>*]", path)]


class _Parsed(Exception):
    """Raised instead of running a script once its parser has read the arguments."""


def _parse_script(path: Path, args: list[str]) -> None:
    """Parse ``args`` with the argparse parser that ``path``'s ``main()`` builds, stopping right after
    parsing (``ArgumentParser.parse_args`` is replaced for the call); a script without argparse takes none."""
    if "argparse" not in path.read_text():
        if args:
            raise SystemExit(f"{path.name} takes no arguments, got {args}")
        return
    spec = importlib.util.spec_from_file_location(f"_doc_{path.stem}", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up there (examples/train_homography.py)
    spec.loader.exec_module(module)
    original = argparse.ArgumentParser.parse_args

    def parse_only(parser, argv=None, namespace=None):
        raise _Parsed(original(parser, args, namespace))

    with mock.patch.object(argparse.ArgumentParser, "parse_args", parse_only), contextlib.suppress(_Parsed):
        module.main()


def _run_sh_tasks() -> dict[str, str]:
    """``scripts/run.sh``'s tasks and what each runs (read from its ``case``)."""
    script = (ROOT / "scripts" / "run.sh").read_text()
    return dict(re.findall(r"^\s*(\w+)\)\s+exec\s+(.*?)\s*;;", script, flags=re.M))


def _check_pytest(args: list[str]) -> None:
    missing = [a for a in args if a.startswith("tests/") and not (ROOT / a.split("::")[0]).exists()]
    if missing:
        raise SystemExit(f"pytest: no such test file {missing}")


def _check_run_sh(args: list[str], inline: bool) -> None:
    """``bash scripts/run.sh TASK ARGS``: the task is one of the script's, and its arguments parse."""
    from sidar_torch import cli

    tasks = _run_sh_tasks()
    task, args = (args[0] if args else None), args[1:]
    if inline and task is None:  # `bash scripts/run.sh` in prose names the script
        return
    if task not in tasks:
        raise SystemExit(f"scripts/run.sh has no task {task!r} (tasks: {', '.join(tasks)})")
    if task == "preview":
        fixed = shlex.split(tasks[task].replace('"$@"', ""))[3:]  # the options run.sh itself passes
        _check_config(cli._parser().parse_args([*fixed, *args]))
    else:
        _check_pytest(args)


def _check_python(args: list[str], inline: bool) -> None:
    """``python -m TOOL ARGS`` or ``python SCRIPT ARGS`` (``args`` follow the interpreter)."""
    from sidar_torch import cli

    if args[0] != "-m":
        script = ROOT / args[0]
        if not script.is_file():
            raise SystemExit(f"no such file {args[0]}")
        _parse_script(script, args[1:])
        return
    tool, args = args[1], args[2:]
    if tool == "sidar_torch":
        parse = cli._parser().parse_args
    elif tool == "pytest":
        parse = _check_pytest
    elif tool.startswith("benchmarks."):
        module = importlib.import_module(tool)
        parse = getattr(module, "parse_args", None) or module.build_parser().parse_args  # soak checks more
    else:
        raise SystemExit(f"python -m {tool}: not a tool of this project")
    if args or not inline:  # a bare `python -m tool` in prose names the tool, whatever it requires
        _check_config(parse(args))


def _check_config(options: argparse.Namespace | None) -> None:
    """The presets (or YAML files) and ``--set`` overrides a command names load, as the tool loads them."""
    from sidar_torch import load_config
    from sidar_torch.cli import parse_overrides

    names = [getattr(options, key, None) for key in ("config", "presets", "preset")]
    names = [name for value in names if value for name in (value if isinstance(value, list) else [value])]
    for name in names or (["misaligned"] if getattr(options, "set", None) else []):
        if "<" in name:  # a placeholder such as <preset>
            continue
        try:
            load_config(ROOT / name if name.endswith((".yaml", ".yml")) else name,
                        **parse_overrides(getattr(options, "set", None) or []))
        except (ValueError, TypeError, OSError) as error:
            raise SystemExit(f"config {name!r}: {error}") from None


def _check_words(words: list[str], inline: bool) -> None:
    """Parse one command (its words after environment variables and ``nice``); raises ``SystemExit``
    with argparse's message if a tool refuses it, as the tool would."""
    if words[0] == "sidar-torch":  # the console script of pyproject.toml
        _check_python(["-m", "sidar_torch", *words[1:]], inline)
    elif words[0] == "bash":
        _check_run_sh(words[2:], inline)
    else:
        _check_python(words[1:], inline)


def command_error(command: str, inline: bool = False) -> str | None:
    """Why ``command`` would not run as documented (argparse's message), or ``None`` if it parses."""
    words = shlex.split(command, comments=not inline)
    while words and (re.fullmatch(r"[A-Z_][A-Z0-9_]*=\S*", words[0]) or words[0] == "nice"):
        words = words[1:]
    if not words or words[0] in OTHER_PROGRAMS:
        return None
    stderr = io.StringIO()
    try:
        with contextlib.redirect_stderr(stderr), contextlib.redirect_stdout(io.StringIO()):
            _check_words(words, inline)
    except SystemExit as stop:
        if stop.code not in (0, None):  # 0: --help
            return (stderr.getvalue().strip().splitlines() or [str(stop.code)])[-1]
    except ModuleNotFoundError as error:
        return str(error)
    return None


def test_the_command_check_refuses_what_the_tools_refuse():
    assert command_error("python -m benchmarks.soak --samples 10000 --size 96x128 --every 500") is None
    assert "HEIGHTxWIDTH" in command_error("python -m benchmarks.soak --samples 10000 --size 96 128")
    assert "unrecognized arguments: --workers" in command_error("python -m benchmarks.bench --workers 0")
    assert "invalid choice" in command_error("python -m sidar_torch preveiw")
    assert "--anchors" in command_error("python -m benchmarks.exposure --samples 2")
    assert "n_veiws" in command_error("python -m sidar_torch preview --set n_veiws=3")
    assert "nope" in command_error("python -m benchmarks.bench --presets misaligned nope")
    assert "no_such.yaml" in command_error("python -m benchmarks.soak --config configs/no_such.yaml")
    assert command_error("python -m benchmarks.exposure", inline=True) is None  # names the tool
    assert "no task" in command_error("bash scripts/run.sh tests")
    assert "--samples" in command_error("bash scripts/run.sh preview --samples two")
    assert "no such test file" in command_error(".venv/bin/python -m pytest tests/test_soak.py")
    assert "--min-soft" in command_error("python scripts/opacity_figure.py --min-soft many")
    assert command_error("PYOPENGL_PLATFORM=egl nice python -m benchmarks.bench --sizes 384x512 --help") is None
    assert command_error("pip install torch") is None


def test_every_documented_command_parses():
    commands = documented_commands()
    for kind in ("python -m sidar_torch", "python -m benchmarks.", "bash scripts/run.sh", "-m pytest", "python scripts/"):
        assert any(kind in command for _, command, _ in commands), kind  # the extraction finds every kind
    broken = [f"{where}: {command}\n    -> {error}" for where, command, inline in commands
              if (error := command_error(command, inline))]
    assert not broken, "\n".join(broken)


def test_every_file_the_docs_name_exists():
    paths = documented_paths()
    assert any(path.startswith("tests/") for _, path in paths)
    missing = [f"{where}: {path}" for where, path in paths if not (ROOT / path).exists()]
    assert not missing, missing


BENCHMARKS = sorted(p.stem for p in (ROOT / "benchmarks").glob("*.py")
                    if "build_parser" in p.read_text() and p.stem != "common")
"""The benchmark modules with a command line."""


def test_benchmarks_tell_users_nothing_about_issue_numbers():
    """What a user reads (``--help`` of every benchmark, the bench's printed report) stands on its own."""
    from benchmarks import bench

    assert len(BENCHMARKS) >= 10, BENCHMARKS
    for name in BENCHMARKS:
        assert "issue" not in importlib.import_module(f"benchmarks.{name}").build_parser().format_help().lower(), name
    machine = {"cpus": 2, "load": 0.5, "python": "3", "torch": "2", "kornia": "0", "gl_platform": "osmesa",
               "lp_num_threads": "0"}
    row = {"preset": "misaligned", "size": "384x512", "views": 6, "s_per_sequence": 0.3, "ms_per_view": 50.0,
           "kornia_ms_per_image": 40.0, "kornia_ratio": 1.25, "warmup_s": 2.0}
    report = {"settings": {"samples": 8, "kornia_calls": 3}, "heap": "warm", "machine": {"before": machine, "after": machine},
              "seconds": 60.0,
              "views": [row], "augment": {**row, "batch": 8, "size": "192x256", "ms_per_image": 100.0,
                                          "plain_ms_per_image": 20.0, "plain_ratio": 5.0, "pool_speedup": 1.1},
              "loaders": {"preset": "misaligned", "size": "384x512", "views": 6, "scaling": 1.5,
                          "sequences_per_s": {"1": 2.0, "2": 3.0}, "first_sample_s": 0.7,
                          "first_sample": {"start": 0.02, "warm_up": 0.0, "sample": 0.6, "handover": 0.08,
                                           "total": 0.7}}}
    report["targets"] = bench.targets(report)
    text = bench.format_report(report)
    assert "## Targets" in text and "issue" not in text.lower(), text


def heading_anchors(page: Path) -> set[str]:
    """The anchors GitHub gives the headings of ``page``: lower case, punctuation dropped, spaces as ``-``."""
    text = re.sub(r"^```.*?^```", "", page.read_text(), flags=re.M | re.S)
    return {re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")
            for heading in re.findall(r"^#+ (.+)$", text, flags=re.M)}


def test_every_link_to_a_section_names_a_heading_of_its_page():
    broken = []
    for page in COMMAND_PAGES:
        for target, anchor in re.findall(r"\]\(([^)#\s]*)#([^)\s]+)\)", page.read_text()):
            linked = page.parent / target if target else page
            if "://" not in target and linked.suffix == ".md" and anchor not in heading_anchors(linked):
                broken.append(f"{page.relative_to(ROOT)} -> {target}#{anchor}")
    assert not broken, broken


def test_reading_a_benchmark_command_line_loads_no_gl():
    """The command checks above run in the fast subset: building every benchmark's parser imports
    neither pyrender nor PyOpenGL (checked in a fresh process)."""
    code = (f"import sys, importlib\nfor name in {BENCHMARKS!r}:\n"
            "    importlib.import_module('benchmarks.' + name).build_parser()\n"
            "print(sorted(m for m in sys.modules if m.split('.')[0] in ('pyrender', 'OpenGL')))")
    result = run(code)
    assert result.returncode == 0 and result.stdout.strip() == "[]", result.stdout[-500:] + result.stderr[-2000:]
