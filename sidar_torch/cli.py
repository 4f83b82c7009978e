"""Command line: ``python -m sidar_torch <command> --help``."""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any, Sequence

import torch
import yaml
from PIL import Image

from .config import available_presets, load_config
from .dataset import SidarDataset
from .io.layout import pixel_entries_text
from .preview import contact_sheet

__all__ = ["main"]


def _parse_set(items: Sequence[str]) -> dict[str, Any]:
    """``key=value`` pairs; values are read as YAML (``n_views=3``, ``fov_deg=[40,60]``)."""
    overrides = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise SystemExit(f"--set {item!r}: expected key=value")
        overrides[key.strip()] = yaml.safe_load(value)
    return overrides


def _preview(args: argparse.Namespace) -> None:
    if args.samples < 1:
        raise SystemExit(f"--samples {args.samples}: expected at least 1")
    config = load_config(args.config, **_parse_set(args.set))
    dataset = SidarDataset(source=args.source, config=config, seed=args.seed)
    start = time.perf_counter()
    samples = [dataset.sample(i) for i in range(args.samples)]
    elapsed = time.perf_counter() - start
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(contact_sheet(samples).permute(1, 2, 0).numpy()).save(out)
    views = args.samples * config.n_views
    print(f"wrote {out} ({args.samples} samples of {config.n_views} views at "
          f"{config.image_size[1]}x{config.image_size[0]}, config {args.config!r})")
    print(f"rendered in {elapsed:.2f} s: {elapsed / args.samples:.3f} s per sample, "
          f"{views / elapsed:.1f} views/s (first sample includes shader compilation)")


def _accuracy(args: argparse.Namespace) -> None:
    from . import accuracy_report

    if args.scenes is not None and args.scenes < 1:
        raise SystemExit(f"--scenes {args.scenes}: expected at least 1")
    try:
        settings = _report_settings(accuracy_report.AccuracySettings, args)
    except (ValueError, FileNotFoundError) as error:
        raise SystemExit(f"accuracy: {error}") from error
    # One thread: the sweep is a long run of tiny tensor operations, which torch's thread pool
    # slows down (a batched 3 x 3 determinant took 16 ms with 2 threads, 15 us with 1).
    torch.set_num_threads(1)
    report = accuracy_report.run_report(settings, log=lambda line: print(line, file=sys.stderr))
    text = accuracy_report.format_report(report)
    print(text)
    if args.json:
        Path(args.json).write_text(json.dumps(report, indent=2))
    if args.markdown:
        Path(args.markdown).write_text(text + "\n")


def _parse_size(text: str) -> tuple[int, int]:
    """``WIDTHxHEIGHT`` (``512x384``) -> ``(H, W)``."""
    w, _, h = text.lower().partition("x")
    try:
        size = (int(h), int(w))
    except ValueError:
        size = (0, 0)
    if min(size) < 1:
        raise argparse.ArgumentTypeError(f"{text!r}: expected WIDTHxHEIGHT in pixels, e.g. 512x384")
    return size


def _bench(args: argparse.Namespace) -> None:
    from . import bench

    changes = {"presets": args.presets, "sizes": args.sizes, "workers": args.workers, "samples": args.samples}
    changes = {k: tuple(v) if isinstance(v, list) else v for k, v in changes.items() if v is not None}
    try:
        factory = bench.BenchSettings.quick if args.quick else bench.BenchSettings
        settings = factory(**changes, overrides=_parse_set(args.set))
        for preset in settings.presets:  # fail before measuring anything
            load_config(preset, **settings.overrides)
    except (ValueError, FileNotFoundError) as error:
        raise SystemExit(f"bench: {error}") from error
    report = bench.run_bench(settings, log=lambda line: print(line, file=sys.stderr))
    text = bench.format_report(report)
    print(text)
    for path, content in ((args.out_md, text + "\n"), (args.out_json, json.dumps(report, indent=2) + "\n")):
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        Path(path).write_text(content)
    print(f"wrote {args.out_md} and {args.out_json}", file=sys.stderr)


def _export(args: argparse.Namespace) -> None:
    from .io import export_dataset

    try:
        config = load_config(args.config, **_parse_set(args.set))
        dataset = SidarDataset(source=args.source, config=config, seed=args.seed)
        summary = export_dataset(dataset, args.out, args.count, start=args.start, shards=args.shards,
                                 workers=args.workers, progress=not args.no_progress)
    except (ValueError, OSError, RuntimeError) as error:
        raise SystemExit(f"export: {error}") from error
    print(f"wrote {len(summary.written)} sequences to {args.out} in {summary.seconds:.1f} s "
          f"({summary.present} of the {args.count} requested were already there); "
          f"read them with sidar_torch.ExportedDataset({args.out!r})")


def _sweep(args: argparse.Namespace) -> None:
    from . import sweep

    try:
        settings = _report_settings(sweep.SweepSettings, args)
    except (ValueError, FileNotFoundError) as error:
        raise SystemExit(f"sweep: {error}") from error
    report = sweep.run_sweep(settings, log=lambda line: print(line, file=sys.stderr))
    print(sweep.format_report(report))
    paths = sweep.write_outputs(report, args.out_dir)
    print(f"wrote {paths['md']}, {paths['json']} and {paths['png']}", file=sys.stderr)


def _schema(args: argparse.Namespace) -> None:
    from .config.schema import schema_markdown

    print(schema_markdown())


def _report_settings(settings_class: Any, args: argparse.Namespace) -> Any:
    """``settings_class`` (``quick()`` with ``--quick``) from ``--config``, ``--set`` and ``--scenes``."""
    changes = {"preset": args.config, "overrides": _parse_set(args.set),
               **({"scenes": args.scenes} if args.scenes is not None else {})}
    return (settings_class.quick if args.quick else settings_class)(**changes)


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
    accuracy = commands.add_parser(
        "accuracy", help="measure warp residuals, homography errors and label PSNR (prints a table)",
        description="Warp residual of H[i, j] on rendered views at 257x131 to 1024x768, homography error "
                    "against the analytic plane-induced homographies over 100,000 scenes, label PSNR.")
    accuracy.add_argument("--quick", action="store_true", help="two small sizes and 2,000 scenes (about a minute)")
    accuracy.add_argument("--scenes", type=int, default=None, help="scenes in the homography sweep")
    _config_options(accuracy, "preset name or YAML path whose cameras the homography sweep draws",
                    "override a config field of every configuration the report loads (repeatable), "
                    "e.g. --set fov_deg=[20,40]; image_size and n_views come from the report's sizes")
    accuracy.add_argument("--json", default=None, help="also write the figures as JSON to this path")
    accuracy.add_argument("--markdown", default=None, help="also write the table as markdown to this path")
    accuracy.set_defaults(run=_accuracy)
    bench = commands.add_parser(
        "bench", help="measure sequences/s, where the time goes, a kornia baseline and memory (prints a table)",
        description="Sequences/s and views/s of each preset and size in this process (median after a "
                    "warm-up sample, with the time of each step) and through a DataLoader; kornia's 2-D "
                    "augmentation pipeline per image at the same sizes and our per-view cost against it; "
                    "peak memory. Prints a markdown table and writes it as markdown and JSON. Full run: "
                    "every preset at 256x192, 512x384 and 1024x768, main process and 1 and 2 workers "
                    "(several minutes on 2 cores).")
    bench.add_argument("--quick", action="store_true",
                       help="misaligned and ambient at 256x192, 4 samples, main process, 1 and 2 workers "
                            "(about a minute); the options below still apply")
    bench.add_argument("--presets", nargs="+", default=None, metavar="PRESET",
                       help=f"presets or YAML paths to measure (default: all of {', '.join(available_presets())})")
    bench.add_argument("--sizes", nargs="+", type=_parse_size, default=None, metavar="WxH",
                       help="output sizes, width x height (default: 256x192 512x384 1024x768)")
    bench.add_argument("--workers", nargs="+", type=int, default=None, metavar="N",
                       help="0 measures in this process, with the time of each step; N >= 1 through a "
                            "DataLoader with N workers (default: 0 1 2)")
    bench.add_argument("--samples", type=int, default=None,
                       help="measured samples per row, after the warm-up (default 8, quick 4)")
    bench.add_argument("--out-md", default="out/bench.md", help="markdown output path (default out/bench.md)")
    bench.add_argument("--out-json", default="out/bench.json", help="JSON output path (default out/bench.json)")
    bench.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                       help="override a config field of every preset (repeatable), e.g. --set n_views=4")
    bench.set_defaults(run=_bench)
    export = commands.add_parser(
        "export", help="write a frozen dataset: the paper's files per sequence, or tar shards (resumable)",
        description="Render sequences START .. START+COUNT-1 and write them to OUT in the SIDAR paper's "
                    f"layout: a folder per sequence with the 8-bit PNGs {pixel_entries_text()} (masks: 255 = "
                    "painting not visible), H_<i>_<j>.mat (homography view i -> view j, Kornia pixels, "
                    "variable H) and cameras.json (K, R, t, image size, homography error); export.json and "
                    "config.yaml at the top. Each sequence appears at once (written to a temporary folder, "
                    "then renamed); rerunning the same command resumes where an interrupted run stopped. "
                    "Read the set back with sidar_torch.ExportedDataset(OUT).")
    export.add_argument("--out", required=True, help="export folder (created if missing; rerun into it to resume)")
    export.add_argument("--count", type=int, required=True, help="number of sequences to export")
    export.add_argument("--start", type=int, default=0, help="first dataset index (default 0)")
    _dataset_options(export)
    export.add_argument("--shards", type=int, default=None, metavar="PER_SHARD",
                        help="write WebDataset-style tar shards shard-00000.tar, ... of PER_SHARD sequences "
                             "each (entries <i>.<file> for the PNGs and cameras.json of a sequence folder, and "
                             "<i>.homographies.npy) instead of one folder per sequence")
    export.add_argument("--workers", type=int, default=0,
                        help="render in this many DataLoader worker processes (default 0: in this process)")
    export.add_argument("--no-progress", action="store_true", help="do not print the progress line on stderr")
    export.set_defaults(run=_export)
    sweep = commands.add_parser(
        "sweep", help="speed against error of the quality knobs: table, JSON and a Pareto-front PNG",
        description="For output sizes 256x192 and 512x384, shadow maps of 256 to 4096 texels, cone and fitted "
                    "shadow frusta and 1x / 2x supersampling, and from a base setting mesh detail, texture "
                    "filter and shadow filter: time per view (median CPU time over the same scenes of the "
                    "preset, this process) against image PSNR versus a reference render (4096 shadow maps, "
                    "fitted frusta, 2x supersampling, finest meshes); warp residual and label PSNR per size. Writes sweep.md, sweep.json and "
                    "sweep.png (Pareto front) into --out-dir. About ten minutes on 2 cores.")
    sweep.add_argument("--quick", action="store_true",
                       help="256x192, shadow maps 256 and 1024 against a 2048 reference, 3 scenes of 3 views "
                            "(under a minute)")
    sweep.add_argument("--scenes", type=int, default=None, help="scenes per setting (default 6, quick 3)")
    _config_options(sweep, "preset name or YAML path the scenes come from",
                    "override a config field of the scenes (repeatable), e.g. --set n_occluders=[1,3]; "
                    "image_size and the swept knobs come from the sweep")
    sweep.add_argument("--out-dir", default="out", help="output folder (default out)")
    sweep.set_defaults(run=_sweep)
    schema = commands.add_parser("schema", help="print every config field with its default, allowed values "
                                                 "and meaning (a markdown table)")
    schema.set_defaults(run=_schema)
    return parser


def main(argv: Sequence[str] | None = None) -> None:
    args = _parser().parse_args(argv)
    args.run(args)
