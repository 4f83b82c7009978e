"""Command line: ``python -m sidar_torch <command> --help``: preview, export, evaluate, schema.

Measurements (speed, accuracy, the quality sweep) live outside the package, in the repository's
``benchmarks/`` (``python -m benchmarks.bench`` and others, from a clone).
"""

from __future__ import annotations

import argparse
import dataclasses
import difflib
import json
import os
import signal
import sys
import time
from pathlib import Path
from typing import Any, ContextManager, Sequence

import yaml
from PIL import Image

from .config import SidarConfig, as_int, available_presets, load_config
from .config.loader import parse_yaml
from .evaluation.baselines import ESTIMATORS, resolve_estimator
from .data.dataset import SidarDataset
from .deep_homography.protocol import PATCH, RHO
from .evaluation.scoring import DEFAULT_TIMEOUT, PROTOCOLS, checked_timeout, evaluate, format_table, testset_names
from .io import LAYOUTS, ExportInterrupted, ExportSummary, export_dataset
from .io import pixel_entries_text
from .orphans import process_age
from .data.preview import contact_sheet
from .evaluation.testsets import available_testsets, export_testset, load_testset
from .timing import stopwatch

__all__ = ["main", "parse_overrides"]


class UsageError(ValueError):
    """A mistake in what the user asked for: printed as one line, exit code 2 (no traceback)."""


USER_MISTAKES = (ValueError, TypeError, OSError, yaml.YAMLError)
"""What reading the user's config, overrides and source raises for a mistake of theirs."""

RENDER_MISTAKES = (ValueError, OSError)
"""What rendering raises for a mistake of the user's: a config whose guarantees no camera meets, an
unreadable image with ``on_bad_image="raise"``, a size this OpenGL context cannot hold (each message
names the field or file). Anything else raised while rendering is a bug and keeps its traceback."""

PIPE_CLOSED_EXIT = 128 + signal.SIGPIPE
"""Exit code when the reader of the output has gone (``| head``): a shell's code for a process
ended by SIGPIPE, as ``cat`` or ``yes`` give."""


def counted(count: int, noun: str) -> str:
    """``count`` and ``noun``, plural unless ``count`` is 1: ``counted(1, "sample")`` is ``"1 sample"``."""
    return f"{count} {noun}{'' if count == 1 else 's'}"


class WallClock:
    """The command's wall time, in parts: ``parts[name]`` holds the seconds spent in each
    ``with clock.part(name):`` block (:func:`sidar_torch.timing.stopwatch`).

    Args:
        age: seconds between the process's start and now (:func:`sidar_torch.orphans.process_age`):
            counted as the part ``start-up`` (the interpreter, its imports and argument parsing);
            ``None`` counts from now.
    """

    def __init__(self, age: float | None):
        self.start = time.perf_counter() - (age or 0.0)
        self.parts: dict[str, float] = {} if age is None else {"start-up": age}

    def part(self, name: str) -> ContextManager[None]:
        """A context manager adding its block's seconds to ``parts[name]``."""
        return stopwatch(self.parts, name)

    def line(self) -> str:
        """``wall time 82.0 s since the process started: start-up 10.1 s, warm-up 48.0 s, export 19.5 s,
        other 4.4 s``: every part, and what no part holds as ``other``."""
        total = time.perf_counter() - self.start
        since = "since the process started" if "start-up" in self.parts else "since the command started"
        parts = [f"{name} {seconds:.1f} s" for name, seconds in self.parts.items()]
        parts.append(f"other {total - sum(self.parts.values()):.1f} s")
        return f"wall time {total:.1f} s {since}: {', '.join(parts)}"


def _yaml_value(text: str) -> str:
    """``text`` with a tuple written in parentheses, ``(192, 256)``, turned into the YAML list ``[192, 256]``."""
    stripped = text.strip()
    return f"[{stripped[1:-1]}]" if stripped.startswith("(") and stripped.endswith(")") else text


def parse_overrides(items: Sequence[str]) -> dict[str, Any]:
    """Config overrides from ``--set`` items: ``key=value`` pairs, values read as YAML (``n_views=3``,
    ``fov_deg=[40,60]``, ``camera_height=[1e-3,1]``; :func:`~sidar_torch.config.loader.parse_yaml`);
    a tuple in parentheses reads as a list (``image_size=(192, 256)``).

    Raises:
        UsageError: an item without ``=``, or a value that is not YAML or nested too deeply to parse
            (the message names the item).
    """
    overrides = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise UsageError(f"--set {item!r}: expected key=value")
        try:
            overrides[key.strip()] = parse_yaml(_yaml_value(value))
        except yaml.YAMLError as error:
            raise UsageError(f"--set {item[:80]!r}: the value is not YAML ({str(error).splitlines()[0]})") from None
        except RecursionError:  # the parser recurses once per level of nesting
            raise UsageError(f"--set {item[:80]!r}: the value is nested too deeply to parse") from None
    return overrides


def _dataset(args: argparse.Namespace, clock: WallClock) -> SidarDataset:
    """The dataset ``--config``, ``--set``, ``--source`` and ``--seed`` ask for, made in ``clock``'s part
    ``set-up`` (reading the config and the source, importing the renderer).

    Raises:
        UsageError: any of them is wrong (the message says which and why).
    """
    overrides = parse_overrides(args.set)
    try:
        with clock.part("set-up"):
            config = load_config(args.config, **overrides)
            return SidarDataset(source=args.source, config=config, seed=args.seed)
    except USER_MISTAKES as error:
        raise UsageError(f"{error}{_list_syntax(str(error), overrides)}") from error


def _list_syntax(message: str, overrides: dict[str, Any]) -> str:
    """How ``--set`` writes a list, when ``message`` is about a list-valued field that ``--set`` gave
    (the config's messages name it as ``config field '<name>'``): `` (--set reads a list as
    image_size=[384, 512] or image_size=(384, 512))``, with the field's default; else ``""``."""
    defaults = {f.name: f.default for f in dataclasses.fields(SidarConfig)}
    for key in overrides:
        if f"config field {key!r}" in message and isinstance(defaults.get(key), tuple):
            items = ", ".join(f"{x:g}" if isinstance(x, float) else str(x) for x in defaults[key])
            return f" (--set reads a list as {key}=[{items}] or {key}=({items}))"
    return ""


def _warm_up(dataset: SidarDataset, clock: WallClock) -> None:
    """Compile every shader variant ``dataset``'s samples can need (:meth:`SidarDataset.warm_up`), timed
    as the part ``warm-up``: Mesa's disk cache then holds them for the DataLoader workers forked afterwards."""
    try:
        with clock.part("warm-up"):
            dataset.warm_up()
    except RENDER_MISTAKES as error:
        raise UsageError(str(error)) from error


def _preview(args: argparse.Namespace, clock: WallClock) -> None:
    if args.samples < 1:
        raise UsageError(f"--samples {args.samples}: expected at least 1")
    out = Path(args.out)
    if out.is_dir() or out.suffix.lower() not in _image_extensions():
        raise UsageError(f"--out {args.out!r}: expected a file path ending in .png, .jpg or another image extension "
                         f"Pillow writes{' (this is a folder)' if out.is_dir() else ''}")
    dataset = _dataset(args, clock)
    config = dataset.config
    try:
        out.parent.mkdir(parents=True, exist_ok=True)  # before rendering, so a wrong --out costs no wait
    except OSError as error:
        raise UsageError(f"--out {args.out!r}: {error}") from error
    _warm_up(dataset, clock)
    try:
        with clock.part("rendering"):
            samples = [dataset.sample(i) for i in range(args.samples)]
    except RENDER_MISTAKES as error:
        raise UsageError(str(error)) from error
    elapsed = clock.parts["rendering"]
    try:
        with clock.part("writing"):
            Image.fromarray(contact_sheet(samples).permute(1, 2, 0).numpy()).save(out)
    except (OSError, ValueError) as error:  # no permission, no such format (Pillow: unknown extension)
        raise UsageError(f"--out {args.out!r}: {error}") from error
    views = args.samples * config.n_views
    print(f"wrote {out} ({counted(args.samples, 'sample')} of {counted(config.n_views, 'view')} at "
          f"{config.image_size[0]}x{config.image_size[1]} (H x W), config {args.config!r})")
    print(f"rendered in {elapsed:.2f} s after the warm-up: {elapsed / args.samples:.3f} s per sample, "
          f"{views / elapsed:.1f} views/s")


def _image_extensions() -> set[str]:
    """The file extensions (``.png``, ``.jpg``, ...) of the formats Pillow can write."""
    return {ext for ext, name in Image.registered_extensions().items() if name in Image.SAVE}


def _export(args: argparse.Namespace, clock: WallClock) -> None:
    if args.testset is not None:
        return _export_testset(args, clock)
    if args.count is None:
        raise UsageError("--count: required (unless --testset names a test set)")
    if args.layout is not None and args.ray:
        raise UsageError(f"--layout {args.layout}: Ray's export writes the folder or shard layout only (drop --ray)")
    if args.ray_address is not None and not args.ray:
        raise UsageError(f"--ray-address {args.ray_address!r}: add --ray to export on a Ray cluster")
    if args.ray and args.workers:
        raise UsageError(f"--workers {args.workers}: renders in DataLoader workers of this process; with --ray "
                         f"Ray's workers render (drop --workers)")
    try:  # export_dataset checks them too: here before the warm-up, so that a wrong number costs no wait
        as_int("count", args.count, 1), as_int("start", args.start, 0)
        if args.shard_size is not None:
            as_int("--shard-size", args.shard_size, 1)
    except ValueError as error:
        raise UsageError(str(error)) from error
    _check_layout(args)
    dataset = _dataset(args, clock)
    if not args.ray:  # Ray's workers are other processes: each warms its own renderer up
        _warm_up(dataset, clock)
    try:
        with clock.part("export"):
            summary = _run_export(args, dataset)
    except ExportInterrupted as interrupted:
        raise _interrupted(f"interrupted after {interrupted.done} of {interrupted.requested} sequences") from None
    except KeyboardInterrupt:
        raise _interrupted("interrupted") from None
    print(f"wrote {counted(len(summary.written), 'sequence')} to {args.out} in {summary.seconds:.1f} s "
          f"({summary.present} of the {counted(args.count, 'requested sequence')} already there); "
          f"read them with sidar_torch.ExportedDataset({args.out!r})")


def _check_layout(args: argparse.Namespace) -> None:
    """``--layout`` and ``--shard-size`` agree (the layout's row of :data:`LAYOUTS` takes the shard size
    given, or none), before any work; the message names the flags, where the layout's names the
    manifest's field."""
    if args.layout is None:
        return
    try:
        LAYOUTS[args.layout].from_record(args.shard_size)
    except ValueError:
        if args.shard_size is None:
            raise UsageError(f"--layout {args.layout}: needs --shard-size SEQUENCES") from None
        raise UsageError(f"--shard-size {args.shard_size}: --layout {args.layout} writes no shards (drop --shard-size; "
                         f"for shards, --layout shards or no --layout)") from None


def _run_export(args: argparse.Namespace, dataset: SidarDataset) -> ExportSummary:
    """Export ``dataset`` as ``args`` say, here or on Ray."""
    try:
        if args.ray:
            from .io.cluster import ray_export

            return ray_export(dataset, args.out, args.count, start=args.start, shard_size=args.shard_size,
                              address=args.ray_address, progress=not args.no_progress)
        return export_dataset(dataset, args.out, args.count, start=args.start, shard_size=args.shard_size,
                              workers=args.workers, progress=not args.no_progress, layout=args.layout)
    except (ValueError, OSError, RuntimeError, ImportError) as error:  # bad arguments, refused folder, lock, no Ray
        raise UsageError(str(error)) from error


TESTSET_PINS = (("--count", "count", None), ("--start", "start", 0), ("--config", "config", "misaligned"),
                ("--set", "set", []), ("--source", "source", None), ("--seed", "seed", 0),
                ("--shard-size", "shard_size", None), ("--layout", "layout", None), ("--ray", "ray", False),
                ("--workers", "workers", 0))
"""Export options a test set pins (its definition gives them): ``(option, attribute, default)``."""


def _export_testset(args: argparse.Namespace, clock: WallClock) -> None:
    """``export --testset NAME --out OUT``: render the set and say whether every file matches its digests."""
    given = [option for option, name, default in TESTSET_PINS if getattr(args, name) != default]
    if given:
        raise UsageError(f"{given[0]}: --testset {args.testset} pins the config, seed, sequences and layout (drop it)")
    try:
        testset = load_testset(args.testset)
    except ValueError as error:
        raise UsageError(str(error)) from error
    try:
        with clock.part("export"):
            check = export_testset(testset, args.out, progress=not args.no_progress)
    except ExportInterrupted as interrupted:
        raise _interrupted(f"interrupted after {interrupted.done} of {interrupted.requested} sequences") from None
    except KeyboardInterrupt:
        raise _interrupted("interrupted") from None
    except (ValueError, OSError, RuntimeError) as error:  # a refused folder, the lock
        raise UsageError(str(error)) from error
    print(f"{testset.name} in {args.out} (one export per category: "
          f"{', '.join(c.name for c in testset.categories)}): {check.summary()}")


def _evaluate(args: argparse.Namespace, clock: WallClock) -> None:
    if args.limit is not None and args.limit < 1:
        raise UsageError(f"--limit {args.limit}: expected at least 1")
    if args.testset not in testset_names() and not Path(args.testset).is_dir():
        raise UsageError(f"--testset {args.testset!r}: expected one of {', '.join(testset_names())} or a folder")
    if args.cache is not None and args.testset not in available_testsets():
        raise UsageError(f"--cache {args.cache!r}: only a named test set is rendered; {args.testset!r} is read as it is")
    _importable_here()
    try:
        checked_timeout(args.timeout)
        resolve_estimator(args.estimator)  # here, so that a wrong name costs no rendering
    except (ValueError, ImportError) as error:
        raise UsageError(f"--{error}" if str(error).startswith(("estimator", "timeout")) else str(error)) from error
    if args.testset in available_testsets():
        where = args.cache if args.cache is not None else "a temporary folder, deleted afterwards (--cache DIR keeps it)"
        print(f"rendering {args.testset} into {where} (what is there already is reused)", file=sys.stderr)
    try:
        with clock.part("evaluate"):
            result = evaluate(args.estimator, testset=args.testset, limit=args.limit, cache=args.cache,
                              progress=not args.no_progress, timeout=args.timeout, protocol=args.protocol,
                              seed=args.seed, patch=args.patch, rho=args.rho)
    except (ValueError, OSError, ImportError) as error:  # not a test set, a damaged file (named), an estimator
        raise UsageError(str(error)) from error  # answering no matrix, a baseline without OpenCV or its weights
    if result["digests"] is not None:
        print(f"{args.testset}: {result['digests']['summary']}")
    print(format_table(result))
    if args.json is not None:
        try:
            Path(args.json).write_text(json.dumps(result, indent=1) + "\n")
        except OSError as error:
            raise UsageError(f"--json {args.json!r}: {error}") from error
        print(f"wrote {args.json}")


def _importable_here() -> None:
    """Let ``--estimator MODULE:FUNCTION`` find MODULE in the current directory under the ``sidar-torch``
    script too: ``python -m`` puts the directory first on ``sys.path``; here it goes last, after what
    is installed."""
    if "" not in sys.path and os.getcwd() not in sys.path:
        sys.path.append(os.getcwd())


def _interrupted(what: str) -> SystemExit:
    """Ctrl-C: print one line saying so and how to resume; the exit to raise, code 130 (128 + SIGINT,
    as a shell's)."""
    print(f"sidar_torch export: {what}; run the same command again to resume", file=sys.stderr)
    return SystemExit(130)


class _Renamed(argparse.Action):
    """An option that was renamed: using it is an error naming the new one."""

    def __init__(self, option_strings: list[str], dest: str, new: str, **kwargs: Any):
        super().__init__(option_strings, dest, **kwargs)
        self.new = new

    def __call__(self, parser: argparse.ArgumentParser, *_: Any) -> None:
        parser.error(f"{'/'.join(self.option_strings)} was renamed {self.new}")


def _schema(args: argparse.Namespace, clock: WallClock) -> None:
    from .config.schema import schema_markdown

    print(schema_markdown())


def _config_options(command: argparse.ArgumentParser, config_help: str, set_help: str) -> None:
    """``--config`` (a preset name or YAML path, default misaligned) and repeatable ``--set KEY=VALUE``."""
    command.add_argument("--config", default="misaligned", help=f"{config_help} (default misaligned)")
    command.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help=set_help)


def _dataset_options(command: argparse.ArgumentParser) -> None:
    """The options naming a dataset: ``--config``, ``--source``, ``--seed`` and ``--set``."""
    _config_options(command, f"preset name ({', '.join(available_presets())}) or YAML path",
                    "override a config field (repeatable), e.g. --set n_views=4 --set image_size=[192,256]")
    command.add_argument("--source", default=None, help="image folder or file (default: built-in paintings)")
    command.add_argument("--seed", type=int, default=0, help="dataset seed: sample i is a function of (seed, i)")


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m sidar_torch", description=__doc__)
    commands = parser.add_subparsers(dest="command", required=True)
    preview = commands.add_parser("preview", help="render samples into a contact sheet PNG")
    _dataset_options(preview)
    preview.add_argument("--samples", type=int, default=3, help="number of samples (rows of the sheet)")
    preview.add_argument("--out", default="preview.png", help="output PNG path")
    preview.set_defaults(run=_preview)
    export = commands.add_parser(
        "export", help="write a frozen dataset: the paper's files per sequence, or tar shards (resumable)",
        description="Render sequences START .. START+COUNT-1 and write them to OUT: a folder per sequence "
                    f"with the paper's file names, the 8-bit PNGs {pixel_entries_text()} (masks: 255 = "
                    "painting not visible), H_<i>_<j>.mat (homography view i -> view j, Kornia pixels, "
                    "variable H) and cameras.json (K, R, t, image size, homography error); export.json and "
                    "config.yaml at the top. Each sequence appears at once (written to a temporary folder, "
                    "then renamed); rerunning the same command resumes where an interrupted run stopped. "
                    "Read the set back with sidar_torch.ExportedDataset(OUT).")
    export.add_argument("--out", required=True, help="export folder (created if missing; rerun into it to resume)")
    export.add_argument("--count", type=int, default=None, help="number of sequences to export (required unless --testset)")
    export.add_argument("--testset", default=None, metavar="NAME",
                        help=f"render a shipped test set ({', '.join(available_testsets())}): one export per "
                             "category in OUT/<category>, checked against the set's recorded SHA-256 digests")
    export.add_argument("--start", type=int, default=0, help="first dataset index (default 0)")
    _dataset_options(export)
    export.add_argument("--shard-size", type=int, default=None, metavar="SEQUENCES",
                        help="write WebDataset-style tar shards shard-00000.tar, ... of SEQUENCES sequences "
                             "each (entries <i>.<file> for the PNGs and cameras.json of a sequence folder, and "
                             "<i>.homographies.npy) instead of one folder per sequence")
    export.add_argument("--layout", choices=sorted(LAYOUTS), default=None,
                        help="paper: the SIDAR paper's own files (H_<i>_<j>.mat as np.savetxt text in its pixels, "
                             "i < j, det = 1; plus homographies.npy and cameras.json); default: folders, or shards "
                             "with --shard-size")
    export.add_argument("--shards", action=_Renamed, help=argparse.SUPPRESS,
                        new="--shard-size (it gives the sequences per shard, not the number of shards)")
    export.add_argument("--workers", type=int, default=0,
                        help="render in this many DataLoader worker processes (default 0: in this process)")
    export.add_argument("--ray", action="store_true",
                        help="render and write in Ray tasks (needs pip install \"ray[data]>=2.9\"): joins the cluster "
                             "in RAY_ADDRESS, else starts a local one; OUT must be a folder every node sees")
    export.add_argument("--ray-address", default=None, metavar="ADDRESS",
                        help="with --ray: the Ray cluster to join, e.g. auto or ray://head:10001")
    export.add_argument("--no-progress", action="store_true", help="do not print the progress line on stderr")
    export.set_defaults(run=_export)
    evaluation = commands.add_parser(
        "evaluate", help="score an estimator on a test set (MACE, success at 1/3/10 px, by category and difficulty)",
        description="Score an estimator on a shipped test set (rendered into --cache, or a temporary folder) or on "
                    "a folder (an export of ours, or the SIDAR paper's own sequences); print the tables.")
    evaluation.add_argument("--testset", default="homography-v1", metavar="NAME_OR_FOLDER",
                            help=f"{', '.join(testset_names())} or a folder (default homography-v1)")
    evaluation.add_argument("--estimator", required=True, metavar="NAME_OR_MODULE:FUNC",
                            help=f"a baseline ({', '.join(ESTIMATORS)}) or MODULE:FUNCTION, a function of two "
                                 "(H, W, 3) uint8 views returning a 3x3 homography (source to target pixels) or None "
                                 "(MODULE in the current directory or on PYTHONPATH)")
    evaluation.add_argument("--limit", type=int, default=None, metavar="N",
                            help="score N pairs only, one from each category in turn (round robin)")
    evaluation.add_argument("--timeout", type=float, default=DEFAULT_TIMEOUT, metavar="SECONDS",
                            help=f"stop a call of the estimator after SECONDS and score its pair as a failure "
                                 f"(default {DEFAULT_TIMEOUT:g}); one that raises is scored so too, its traceback "
                                 f"printed, and the run goes on")
    evaluation.add_argument("--protocol", default="views", choices=PROTOCOLS,
                            help="views: view 0 to each other view, whole (default); patches: the patch-pair protocol, "
                                 "a box of view i and the same box of view j brought back and moved by a seeded "
                                 "random corner perturbation, for every ordered view pair (docs/benchmarks.md)")
    evaluation.add_argument("--patch", type=int, default=PATCH, metavar="PX",
                            help=f"the patch protocol's box side (default {PATCH})")
    evaluation.add_argument("--rho", type=float, default=RHO, metavar="PX",
                            help=f"the patch protocol's largest corner perturbation per coordinate (default {RHO})")
    evaluation.add_argument("--seed", type=int, default=0, help="the patch protocol's seed (default 0)")
    evaluation.add_argument("--cache", default=None, metavar="DIR",
                            help="render a named test set into DIR and keep it (default: a temporary folder)")
    evaluation.add_argument("--json", default=None, metavar="OUT", help="also write the result as JSON to OUT")
    evaluation.add_argument("--no-progress", action="store_true", help="do not print the rendering's progress")
    evaluation.set_defaults(run=_evaluate)
    schema = commands.add_parser("schema", help="print every config field with its default, allowed values "
                                                 "and meaning (a markdown table)")
    schema.set_defaults(run=_schema)
    parser.command_names = tuple(commands.choices)  # for _did_you_mean
    return parser


def _silence_stdout() -> None:
    """Point stdout at ``os.devnull``, so that flushing what is left at exit raises nothing."""
    try:
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    except (AttributeError, OSError, ValueError):  # not a file descriptor (e.g. captured in a test)
        pass


def _did_you_mean(parser: argparse.ArgumentParser, argv: Sequence[str]) -> None:
    """Exit through ``parser.error`` (code 2) naming the closest command when the first argument that is
    not an option is no command (``preveiw``: did you mean 'preview'?); else return."""
    commands = parser.command_names
    word = next((arg for arg in argv if not arg.startswith("-")), None)
    if word is not None and word not in commands:
        close = difflib.get_close_matches(word, commands, n=1)
        hint = f"did you mean {close[0]!r}?" if close else f"expected one of {', '.join(commands)}"
        parser.error(f"unknown command {word!r} ({hint})")


def main(argv: Sequence[str] | None = None) -> None:
    """Run a command. Called without ``argv`` (``python -m sidar_torch``, the ``sidar-torch`` script) it
    reads ``sys.argv`` and its last line gives the wall time since the process started, with the
    start-up (interpreter and imports), the warm-up (shader compilation) and the command's work
    apart (:class:`WallClock`); with ``argv`` (a call from Python) the time counts from the call.
    A user's mistake prints one line, ``sidar_torch <command>: <what is wrong>``, and
    exits with code 2 (as argparse does for bad options); anything else is a bug and keeps its traceback.
    When the reader of the output goes away (``python -m sidar_torch schema | head``), the command
    stops quietly with exit code :data:`PIPE_CLOSED_EXIT` (the only pipes a command writes to are
    stdout and stderr, so a ``BrokenPipeError`` means one of them)."""
    clock = WallClock(process_age(os.getpid()) if argv is None else None)
    parser = _parser()
    _did_you_mean(parser, sys.argv[1:] if argv is None else argv)
    args = parser.parse_args(argv)
    try:
        args.run(args, clock)
        if args.command != "schema":  # schema's output is a document, piped into files
            print(clock.line())
        sys.stdout.flush()  # here, so that a closed pipe raises inside this try rather than at exit
    except UsageError as error:
        print(f"sidar_torch {args.command}: {error}", file=sys.stderr)
        raise SystemExit(2) from None
    except BrokenPipeError:
        _silence_stdout()
        raise SystemExit(PIPE_CLOSED_EXIT) from None
