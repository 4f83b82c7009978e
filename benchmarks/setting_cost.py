"""What a rendering setting costs: median time per view of the same scenes drawn two ways, same run.
``python -m benchmarks.setting_cost --field NAME [--values A B] [--config P] [--set K=V]`` from the
repository root: the one command of the renderer's two-way comparisons.

``NAME`` with ``--values A B`` is a config field that changes how the scenes are drawn, not what they
hold (e.g. ``shadow_map_size``), or a ``RenderSettings`` field that no config field sets (e.g.
``footprint_tile``), at two values. Without ``--values`` it is drawn off and on: a ``RenderSettings``
switch (``mirrors``, the painting's reflections and refraction; a skip of work that cannot change a
pixel: ``split_shadow_lookups``, ``clear_written_texels``, ``skip_idle_shadows``, ``cull_occluders``,
``reuse_shadow_maps``, ``masks_from_outline``, ``masks_from_stencil``, ``label_from_painting``) or an
optional output the renderer draws (``opacities``, ``shadow_masks``, ``shadow_free``, ``depth``), without
and with.

Renders each sequence both ways (``benchmarks.paired``) and prints what each way gives the renderer,
then per view the medians and the median paired difference (the second way minus the first) in
wall-clock and this process's CPU time, then what :data:`NOTES` adds for the field (the views with a
mirror program, an output's own steps, what a skip leaves out), then how far the views differ.

    python -m benchmarks.setting_cost --field shadow_map_size --values 1024 auto --size 384x512 --samples 40
    python -m benchmarks.setting_cost --field footprint_tile --values 32 16 --size 192x256 --samples 40
    python -m benchmarks.setting_cost --field mirrors --config paper_misaligned --size 384x512 --samples 40
    python -m benchmarks.setting_cost --field opacities --config misaligned --size 384x512 --samples 60
    python -m benchmarks.setting_cost --field shadow_masks --config misaligned --size 384x512 --samples 40
    python -m benchmarks.setting_cost --field split_shadow_lookups --config misaligned --size 384x512 --samples 40

It replaces the former ``mirror_cost``, ``opacity_cost``, ``output_cost --output NAME`` and ``skip_cost``
(the docs name them beside the figures they measured). The other ``*_cost`` commands compare something else than two renderer
settings in one process, so they stay apart: ``effects_cost`` (the view effects, a CPU step after
the render), ``lens_cost`` (three lens models through ``sample.render_arrays``, whose lens step follows
the read-back), ``shader_cost`` (our GLSL with pieces cut out, a renderer per cut) and
``revision_cost`` (two checkouts, in fresh processes).
"""

from __future__ import annotations

import argparse
import statistics
from dataclasses import fields, replace
from typing import Any, Callable

import numpy as np

from sidar_torch import SidarDataset

from .common import parse_set, size_label
from .paired import paired_config, paired_parser, paired_settings_times, print_paired

Steps = list[tuple[dict, dict]]
"""Each measured sequence's ``(timings of the first way, of the second)`` (``SceneRenderer.render``'s steps, s)."""

Note = Callable[[Any, int], Callable[[Steps], str]]
"""``(config, samples) -> (steps -> line)``: called before the run (to read what it needs first), its
result after it."""


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``python -m benchmarks.setting_cost``; parsing it runs nothing."""
    parser = paired_parser("setting_cost", __doc__.splitlines()[0], samples=40, set_example="n_occluders=[1,3]")
    parser.add_argument("--field", required=True, help="the config field compared, e.g. shadow_map_size, a "
                        "RenderSettings field no config field sets, e.g. footprint_tile, or without --values a "
                        "RenderSettings switch (mirrors, split_shadow_lookups, ...) or a drawn output (depth, ...)")
    parser.add_argument("--values", nargs=2, metavar=("A", "B"),
                        help="its two values (read as YAML), e.g. 1024 auto; without: off and on")
    return parser


def main(argv: list[str] | None = None) -> None:
    args = build_parser().parse_args(argv)
    config = paired_config("setting_cost", args)
    try:
        labels, settings = compared_settings(config, args.field, args.values)
    except ValueError as error:
        raise SystemExit(f"setting_cost: {error}") from error
    changed = sorted(f.name for f in fields(settings[0]) if getattr(settings[0], f.name) != getattr(settings[1], f.name))
    if not changed:
        raise SystemExit(f"setting_cost: {args.field} = {labels[0]} and {labels[1]} give the renderer the "
                         "same settings (a field of the scenes, not of how they are drawn?)")
    note = NOTES.get(args.field, lambda config, samples: None)(config, args.samples)
    differences = ViewDifference()
    ms_per_view, steps = paired_settings_times(config, *settings, args.samples, differences)
    given = "; ".join(f"{label}: " + ", ".join(f"{n}={_shown(getattr(s, n))}" for n in changed)
                      for label, s in zip(labels, settings))
    print(f"{args.field}: {args.config} {' '.join(args.set)} {size_label(args.size)} (H x W), {args.samples} sequences "
          f"x {config.n_views} views; renderer: {given}")
    print_paired(ms_per_view, labels)
    if note:
        print(note(steps))
    print(differences.line(labels))


def compared_settings(config: Any, field: str, values: list[str] | None) -> tuple[tuple[str, str], list[Any]]:
    """The labels and ``RenderSettings`` of the two ways: ``field`` at ``values`` (:func:`value_settings`),
    or, without values, a boolean ``RenderSettings`` field False and True, or a drawn output
    (``choices.outputs.OUTPUTS``) left out of and put in ``RenderSettings.outputs``.

    Raises:
        ValueError: naming the field: unknown, a value out of its range, or neither a switch nor an output.
    """
    from sidar_torch.render import RenderSettings  # imports the renderer: here, so parsing loads no GL
    from sidar_torch.choices.outputs import OUTPUTS

    if values:
        return (values[0], values[1]), [value_settings(config, field, value) for value in values]
    settings = RenderSettings.from_config(config)
    if field in OUTPUTS:
        return ("without", "with"), [replace(settings, outputs=settings.outputs - {field}),
                                     replace(settings, outputs=settings.outputs | {field})]
    if not isinstance(getattr(settings, field, None), bool):
        raise ValueError(f"{field}: not a RenderSettings switch nor an output the renderer draws; "
                         "give its two values (--values A B)")
    return ("off", "on"), [replace(settings, **{field: flag}) for flag in (False, True)]


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


def _shown(value: Any) -> Any:
    """A settings value as printed: a set sorted (``outputs``), anything else as it is."""
    return sorted(value) if isinstance(value, frozenset) else value


# --- what a field adds to the two lines of times -------------------------------------------------


def mirrored_views(config: Any, samples: int) -> Callable[[Steps], str]:
    """Note of ``mirrors``: the views that draw an occluder with a mirror program variant (a reflective or
    glass material, quirk 8); the other views run the same programs either way."""
    from sidar_torch.render.mirror import mirror_define  # imports pyrender: here, so parsing loads no GL

    dataset = SidarDataset(config=config, seed=0)
    views = [v for i in range(samples) for v in dataset.scene(i).views]
    mirrored = sum(any(mirror_define(o.material) for o in v.occluders) for v in views)
    return lambda steps: f"{mirrored} of {len(views)} views have a reflective or glass occluder"


def step_difference(*names: str, remark: str = "") -> Note:
    """Note of an output: the median paired difference, per view (wall), of the steps of
    ``SceneRenderer.render``'s timings that its work is timed under (``names``)."""
    def note(config: Any, samples: int) -> Callable[[Steps], str]:
        def line(steps: Steps) -> str:
            ms = [1e3 * sum(on.get(n, 0.0) - off.get(n, 0.0) for n in names) / config.n_views for off, on in steps]
            return f"{' + '.join(names)} (wall): median paired difference {statistics.median(ms):+.2f} ms / view{remark}"
        return line
    return note


def lookups_kept(config: Any, samples: int) -> tuple[float, float]:
    """``(share of the painting's lookups kept, median draws per view with a split)`` over the
    first ``samples`` sequences' plans (views whose painting is drawn with shadow lookups; no GL)."""
    from sidar_torch.render import RenderSettings  # imports pyrender: here, so parsing loads no GL
    from sidar_torch.render.plan import plan_views
    from sidar_torch.render.visibility import painting_mask

    dataset, settings = SidarDataset(config=config, seed=0), RenderSettings.from_config(config)
    kept = full = 0
    draws = []
    for index in range(samples):
        sequence = dataset.scene(index)
        for view, plan in zip(sequence.views, plan_views(sequence, settings)):
            if not plan.n_shadowed:
                continue
            seen = ~painting_mask(view.camera.K, view.camera.R, view.camera.t, config.image_size)
            full += int(seen.sum()) * plan.n_shadowed
            parts = plan.painting_parts
            kept += (sum(int(seen[p.y:p.y + p.height, p.x:p.x + p.width].sum()) * (p.end - p.begin) for p in parts)
                     if parts else int(seen.sum()) * plan.n_shadowed)
            draws.append(max(1, len(parts)))
    return kept / max(full, 1), statistics.median(draws) if draws else 0.0


def lookups_note(config: Any, samples: int) -> Callable[[Steps], str]:
    """Note of ``split_shadow_lookups`` (``render.footprints``): :func:`lookups_kept`."""
    share, draws = lookups_kept(config, samples)
    return lambda steps: (f"the split keeps {100 * share:.0f} % of the painting's shadow lookups, in {draws:g} draws "
                          "per view (median)")


def cleared_texels(config: Any) -> tuple[np.ndarray, np.ndarray]:
    """The depth and transmittance map texels that the renderers of ``config`` with
    ``clear_written_texels`` on and off have cleared so far in this process (shared renderers: other
    work in the process counts too, so take differences): ``(on, off)``, each ``[depth, transmittance]``."""
    from sidar_torch.render import RenderSettings, shared_renderer

    settings = RenderSettings.from_config(config)
    on, off = (shared_renderer(replace(settings, clear_written_texels=flag))._passes for flag in (True, False))
    return tuple(np.array([gl.shadow_maps.cleared_texels, gl.transmittance.cleared_texels]) for gl in (on, off))


def texels_note(config: Any, samples: int) -> Callable[[Steps], str]:
    """Note of ``clear_written_texels`` (``render.shadow_array``): the share of the shadow and
    transmittance maps' texels cleared, this run's clears only (:func:`cleared_texels` before and after)."""
    before = cleared_texels(config)

    def line(steps: Steps) -> str:
        (on, off), (on_before, off_before) = cleared_texels(config), before
        depth, tints = (on - on_before) / np.maximum(off - off_before, 1)
        return f"{100 * depth:.0f} % of the depth maps' texels cleared, {100 * tints:.0f} % of the transmittance maps'"
    return line


_SHADOWED = " (views without a shadowed light add nothing)"

NOTES: dict[str, Note] = {
    "mirrors": mirrored_views,
    "opacities": step_difference("opacity", remark=" (views without a visible occluder skip it)"),
    "shadow_masks": step_difference("shadow_mask", remark=_SHADOWED),
    "shadow_free": step_difference("colour", "readback", remark=_SHADOWED),
    "depth": step_difference("depth", "readback"),
    "split_shadow_lookups": lookups_note,
    "clear_written_texels": texels_note,
}
"""Field -> the line it adds after the times (the other fields add none)."""


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
