"""What a rendering setting costs: median time per view of the same scenes rendered with two values
of one config field that changes how they are drawn, not what they hold (e.g. ``shadow_map_size``),
or of a ``RenderSettings`` field that no config field sets (e.g. ``footprint_tile``), same run.
``python -m benchmarks.setting_cost --field NAME --values A B [--config P] [--set K=V]`` from the
repository root.

Renders each sequence with the renderer settings of ``A`` and of ``B`` (``benchmarks.paired``) and
prints what each value gives the renderer, then per view the medians and the median paired
difference (``B`` minus ``A``) in wall-clock and this process's CPU time.

    python -m benchmarks.setting_cost --field shadow_map_size --values 1024 auto --size 384x512 --samples 40
    python -m benchmarks.setting_cost --field footprint_tile --values 32 16 --size 192x256 --samples 40
"""

from __future__ import annotations

import argparse
from dataclasses import fields, replace
from typing import Any

import numpy as np

from .common import parse_set, size_label
from .paired import paired_config, paired_parser, paired_settings_times, print_paired


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``python -m benchmarks.setting_cost``; parsing it runs nothing."""
    parser = paired_parser("setting_cost", __doc__.splitlines()[0], samples=40, set_example="n_occluders=[1,3]")
    parser.add_argument("--field", required=True, help="the config field compared, e.g. shadow_map_size, "
                        "or a RenderSettings field no config field sets, e.g. footprint_tile")
    parser.add_argument("--values", nargs=2, required=True, metavar=("A", "B"),
                        help="its two values (read as YAML), e.g. 1024 auto")
    return parser


def main(argv: list[str] | None = None) -> None:
    args = build_parser().parse_args(argv)
    config = paired_config("setting_cost", args)
    try:
        settings = [value_settings(config, args.field, value) for value in args.values]
    except ValueError as error:
        raise SystemExit(f"setting_cost: {error}") from error
    changed = {name for name in settings[0].__dataclass_fields__ if getattr(settings[0], name) != getattr(settings[1], name)}
    if not changed:
        raise SystemExit(f"setting_cost: {args.field} = {args.values[0]} and {args.values[1]} give the renderer the "
                         "same settings (a field of the scenes, not of how they are drawn?)")
    differences = ViewDifference()
    ms_per_view, _ = paired_settings_times(config, *settings, args.samples, differences)
    given = "; ".join(f"{value}: " + ", ".join(f"{n}={getattr(s, n)}" for n in sorted(changed))
                      for value, s in zip(args.values, settings))
    print(f"{args.field}: {args.config} {' '.join(args.set)} {size_label(args.size)} (H x W), {args.samples} sequences "
          f"x {config.n_views} views; renderer: {given}")
    print_paired(ms_per_view, tuple(args.values))
    print(differences.line(tuple(args.values)))


def value_settings(config: Any, field: str, value: str) -> Any:
    """The ``RenderSettings`` that ``config`` with ``field`` set to ``value`` (read as YAML) gives the
    renderer: a config field through the config, a renderer field that no config field sets (e.g.
    ``footprint_tile``) on the config's settings.

    Raises:
        ValueError: an unknown field, or a value out of the field's range, naming the field.
    """
    from sidar_torch.render import RenderSettings  # imports pyrender: here, so parsing loads no GL

    parsed = parse_set([f"{field}={value}"])
    if field in _field_names(config) or field not in _field_names(RenderSettings):
        return RenderSettings.from_config(config.replace(**parsed))  # an unknown field: the config names it
    return replace(RenderSettings.from_config(config), **parsed)


def _field_names(dataclass_or_instance: Any) -> set[str]:
    return {f.name for f in fields(dataclass_or_instance)}


class ViewDifference:
    """A running summary of how far one value's views are from the other's: :meth:`append` takes a
    sequence's ``(V, H, W, 3)`` difference in 8-bit levels (int), so no sequence's difference is kept."""

    def __init__(self) -> None:
        self.views = self.same = self.values = self.squares = self.absolute = self.largest = 0

    def append(self, difference: np.ndarray) -> None:
        levels = np.abs(difference.astype(np.int64))
        self.views += len(levels)
        self.same += int((levels.reshape(len(levels), -1) == 0).all(axis=1).sum())
        self.values += levels.size
        self.squares += int(np.square(levels).sum())
        self.absolute += int(levels.sum())
        self.largest = max(self.largest, int(levels.max(initial=0)))

    def line(self, labels: tuple[str, str]) -> str:
        """PSNR (dB, peak 255) over every view, views with the same bytes, mean absolute and largest
        difference, of ``labels[1]``'s views against ``labels[0]``'s."""
        mse = self.squares / self.values
        psnr = "inf (the same bytes)" if mse == 0 else f"{10 * np.log10(255 ** 2 / mse):.2f} dB"
        return (f"views: {labels[1]} against {labels[0]}: PSNR {psnr}; {self.same} of {self.views} views the same "
                f"bytes; mean |difference| {self.absolute / self.values:.3f} levels, largest {self.largest}")


def view_difference(differences: list[np.ndarray], labels: tuple[str, str]) -> str:
    """:meth:`ViewDifference.line` of the sequences' differences ``differences``."""
    summary = ViewDifference()
    for difference in differences:
        summary.append(difference)
    return summary.line(labels)

if __name__ == "__main__":
    main()
