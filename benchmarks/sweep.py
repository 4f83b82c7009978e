"""Speed against error: ``python -m benchmarks.sweep [--quick] [--out-dir DIR]`` from the repository root.

Sweeps the renderer's quality knobs and reports, for every setting, the time per view against
the error it leaves:

* **knobs**: output resolution, shadow-map size (``SidarConfig.shadow_map_size``) and frustum
  (``shadow_frustum``: the light's cone or fitted to what the cameras see) crossed with
  supersampling ``s`` (views drawn at ``s`` times the resolution, then area-averaged ``s x s``
  in linear light, see :func:`render_views`); then, one at a time from a base setting (fitted
  frusta, no supersampling), occluder mesh detail (``mesh_detail`` "auto" at each
  ``mesh_error_px``), the painting's texture filter (``texture_filter``), the shadow filter
  (``shadow_filter``) and multisample antialiasing of the colour pass (``antialias`` samples per
  pixel). Every other setting uses fixed meshes, trilinear filtering and one sample per pixel
  (``--only KNOB``: the base setting, that knob's variations and the reference, nothing else);
* **time per view**: median over the same ``scenes`` sequences of the default preset, in this
  process (one untimed warm-up sequence per setting first), of the renderer's whole call
  (views, masks and label; for ``s > 1`` the larger draw and the downsampling) divided by the
  number of views. Torch runs one thread, llvmpipe rasterises in the calling thread (as in
  ``benchmarks.bench``), so figures are per core. The time is this process's CPU time
  (``time.process_time``), not wall time: other jobs sharing the cores would otherwise dominate
  the differences between settings (in a quick sweep at load 7, wall times of settings doing
  nearly the same work differed up to 3x);
* **image PSNR** (dB) of the views against a high-quality reference render of the same scenes at
  the same output size: largest shadow maps with fitted frusta, supersampled, the finest occluder
  meshes, trilinear filtering, one sample per pixel of the large draw
  (:attr:`SweepSettings.reference`).
  One PSNR per setting, from the mean squared error over every pixel of every view of every
  scene (occluders and background included);
* **warp residual** (median / max Lucas-Kanade displacement, pixels; see
  :func:`benchmarks.metrics.warp_residuals`) per resolution and supersampling, on ambient,
  occluder-free speckle scenes (no lights, so the shadow-map size cannot change them);
* **label PSNR** (:func:`benchmarks.accuracy_report.label_row`) per resolution. The label is an
  unlit, fronto-parallel, occluder-free draw that shows the texture exactly; it does not depend
  on the shadow maps, and a supersampled preset would still draw it at the output size.

Supersampled cameras: pixel ``(u, v)`` of the output averages pixels ``(su + a, sv + b)``,
``0 <= a, b < s``, of the large draw, whose centres average to ``(su + (s - 1) / 2, ...)``. So
the large camera is ``K_s = [[s, 0, (s - 1) / 2], [0, s, (s - 1) / 2], [0, 0, 1]] @ K``, which
puts every output pixel's centre exactly where ``K`` does: the homographies are unchanged. The
painting texture is upsampled bilinearly (texel centres kept), which is what magnifying the
original texture samples anyway.

A setting is **Pareto-optimal** (at its resolution) when no other setting of that resolution is
at least as fast and at least as close to the reference, and strictly better in one. The
reference itself is left out of the front (its PSNR against itself is infinite).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import sys
import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any, Callable

import numpy as np
import torch
import torch.nn.functional as F

from sidar_torch.sample.effects import linear_to_srgb, srgb_to_linear
from sidar_torch.config import ANTIALIAS_SAMPLES, SHADOW_FILTERS, SHADOW_FRUSTA, TEXTURE_FILTERS, load_config
from sidar_torch.data.dataset import SidarDataset
from .metrics import psnr, speckle_paintings, warp_residuals
from sidar_torch import render  # render.SceneRenderer loads the renderer at its first use, not at import
from sidar_torch.render import RenderSettings
from sidar_torch.sample import sequence_homographies
from sidar_torch.scene import SceneSequence

from .accuracy_report import label_row
from .common import DEFAULT_PRESET, one_thread, parse_set, parse_size, size_label

__all__ = ["Setting", "SweepSettings", "build_parser", "format_report", "main", "pareto_front", "plot_front",
           "render_views", "run_sweep", "supersampled_sequence", "write_outputs"]

KNOBS = ("mesh_detail", "texture_filter", "shadow_filter", "antialias")
"""The knobs varied one at a time from the base setting (``SweepSettings.only`` picks one)."""

_WARMUP_INDEX = 1_000_000
"""Index of each setting's untimed warm-up sequence, apart from the measured ``0 .. scenes - 1``."""


@dataclass(frozen=True)
class Setting:
    """One point of the sweep: the renderer's quality knobs.

    Attributes:
        shadow_map_size: texels (power of two).
        supersampling: factor ``s`` (1: none).
        shadow_frustum: ``"cone"`` or ``"fitted"`` (``SidarConfig.shadow_frustum``).
        mesh_error_px: ``None``: fixed occluder meshes; else ``mesh_detail`` "auto" with this
            ``mesh_error_px`` (0: the finest level).
        texture_filter: ``"trilinear"`` or ``"bilinear"`` (``SidarConfig.texture_filter``).
        shadow_filter: ``"tent"`` or ``"bilinear"`` (``SidarConfig.shadow_filter``).
        antialias: samples per pixel of the colour pass (``SidarConfig.antialias``; 1: none).
    """

    shadow_map_size: int
    supersampling: int
    shadow_frustum: str = "cone"
    mesh_error_px: float | None = None
    texture_filter: str = "trilinear"
    shadow_filter: str = "tent"
    antialias: int = 1

    @property
    def mesh_detail(self) -> str:
        """``"fixed"``, ``"finest"`` or ``"<= x px"``."""
        if self.mesh_error_px is None:
            return "fixed"
        return "finest" if self.mesh_error_px == 0 else f"<= {self.mesh_error_px:g} px"

    def label(self) -> str:
        """Short label for the plot: ``map/sx`` and the frustum, mesh and filter when not the default."""
        parts = [f"{self.shadow_map_size}/{self.supersampling}x", "fit" if self.shadow_frustum == "fitted" else ""]
        parts += ["" if self.mesh_error_px is None else f"mesh {self.mesh_detail}",
                  "" if self.texture_filter == "trilinear" else self.texture_filter,
                  "" if self.shadow_filter == "tent" else f"{self.shadow_filter} shadows",
                  "" if self.antialias == 1 else f"msaa {self.antialias}"]
        return " ".join(p for p in parts if p)


@dataclass(frozen=True)
class SweepSettings:
    """What the sweep measures.

    Attributes:
        sizes: output sizes ``(H, W)``.
        shadow_map_sizes: shadow-map sides, texels (powers of two).
        supersampling: factors ``s`` (1: none).
        shadow_frusta: frusta crossed with the sizes, factors and shadow filters.
        mesh_errors: ``mesh_error_px`` values tried (``mesh_detail`` "auto") at the base setting.
        texture_filters: filters tried at the base setting (``"trilinear"`` is every setting's).
        shadow_filters: shadow filters crossed with the sizes, factors and frusta (the one-at-a-time
            variations keep ``"tent"``).
        antialias: samples per pixel tried at the base setting (1 is every setting's).
        only: ``None``: every setting; one of :data:`KNOBS`: only the base setting, that knob's
            variations and the reference.
        base_shadow_map_size: shadow map of the base setting (fitted frusta, no supersampling)
            from which mesh detail and texture filtering vary.
        reference: ``(shadow_map_size, supersampling)`` of the reference render (fitted frusta,
            the finest meshes, trilinear filtering).
        scenes: sequences of ``preset`` per setting (timed and compared with the reference).
        residual_samples: ambient speckle samples per resolution and factor for the warp residual.
        label_samples: samples per resolution for the label PSNR.
        preset: the configuration the scenes come from.
        n_views: views per sequence (``None``: the preset's).
        seed: dataset seed.
        overrides: config fields applied to ``preset`` (``image_size`` comes from ``sizes``, and
            the swept knobs from the settings).
    """

    sizes: tuple[tuple[int, int], ...] = ((192, 256), (384, 512))
    shadow_map_sizes: tuple[int, ...] = (256, 512, 1024, 2048, 4096)
    supersampling: tuple[int, ...] = (1, 2)
    shadow_frusta: tuple[str, ...] = ("cone", "fitted")
    mesh_errors: tuple[float, ...] = (0.25, 1.0, 4.0)
    texture_filters: tuple[str, ...] = ("trilinear", "bilinear")
    shadow_filters: tuple[str, ...] = ("tent", "bilinear")
    antialias: tuple[int, ...] = (1, 4)
    base_shadow_map_size: int = 1024
    reference: tuple[int, int] = (4096, 2)
    scenes: int = 6
    residual_samples: int = 3
    label_samples: int = 3
    preset: str = DEFAULT_PRESET
    n_views: int | None = None
    seed: int = 0
    overrides: dict[str, Any] = field(default_factory=dict)
    only: str | None = None

    def __post_init__(self) -> None:
        if "image_size" in self.overrides:
            raise ValueError("overrides: image_size comes from sizes; leave it out")
        load_config(self.preset, **self.overrides)  # unknown or invalid fields fail before measuring
        if not self.sizes or not self.shadow_map_sizes or not self.supersampling:
            raise ValueError("sizes, shadow_map_sizes and supersampling: expected at least one each")
        if any(len(size) != 2 or min(size) < 1 for size in self.sizes):
            raise ValueError(f"sizes: expected (H, W) pairs of positive integers, got {self.sizes}")
        if any(s < 16 or s & (s - 1) for s in (*self.shadow_map_sizes, self.reference[0], self.base_shadow_map_size)):
            raise ValueError(f"shadow_map_sizes, reference, base_shadow_map_size: expected powers of two >= 16, got "
                             f"{self.shadow_map_sizes}, {self.reference}, {self.base_shadow_map_size}")
        if not self.shadow_frusta or not set(self.shadow_frusta) <= set(SHADOW_FRUSTA):
            raise ValueError(f"shadow_frusta: expected a non-empty subset of {SHADOW_FRUSTA}, got {self.shadow_frusta}")
        if not set(self.shadow_filters) <= set(SHADOW_FILTERS):
            raise ValueError(f"shadow_filters: expected a subset of {SHADOW_FILTERS}, got {self.shadow_filters}")
        if not set(self.texture_filters) <= set(TEXTURE_FILTERS):
            raise ValueError(f"texture_filters: expected a subset of {TEXTURE_FILTERS}, got {self.texture_filters}")
        if not set(self.antialias) <= set(ANTIALIAS_SAMPLES):
            raise ValueError(f"antialias: expected a subset of {ANTIALIAS_SAMPLES}, got {self.antialias}")
        if self.only is not None and self.only not in KNOBS:
            raise ValueError(f"only: expected None or one of {KNOBS}, got {self.only!r}")
        if any(not e >= 0 for e in self.mesh_errors):
            raise ValueError(f"mesh_errors: expected pixels >= 0, got {self.mesh_errors}")
        if any(s < 1 for s in (*self.supersampling, self.reference[1])):
            raise ValueError(f"supersampling, reference: expected factors >= 1, got {self.supersampling}, "
                             f"{self.reference}")
        if min(self.scenes, self.residual_samples, self.label_samples) < 1:
            raise ValueError("scenes, residual_samples, label_samples: expected >= 1")

    @classmethod
    def quick(cls, **changes: Any) -> "SweepSettings":
        """A few minutes on 2 cores: 256x192, shadow maps 256 / 1024 (reference 2048), 3 scenes of 3 views."""
        return cls(**{"sizes": ((192, 256),), "shadow_map_sizes": (256, 1024), "supersampling": (1, 2),
                      "mesh_errors": (0.25, 2.0), "base_shadow_map_size": 256, "reference": (2048, 2), "scenes": 3,
                      "residual_samples": 2, "label_samples": 2, "n_views": 3, **changes})

    @property
    def reference_setting(self) -> Setting:
        return Setting(*self.reference, "fitted", 0.0)

    def settings(self) -> list[Setting]:
        """Every setting measured at each size: the grid, the one-at-a-time variations, the reference
        (with :attr:`only`: the base setting, that knob's variations, the reference)."""
        base = Setting(self.base_shadow_map_size, 1, "fitted")
        variations = {
            "mesh_detail": [replace(base, mesh_error_px=e) for e in self.mesh_errors],
            "texture_filter": [replace(base, texture_filter=f) for f in self.texture_filters if f != "trilinear"],
            "shadow_filter": [replace(base, shadow_filter=f) for f in self.shadow_filters if f != "tent"],
            "antialias": [replace(base, antialias=a) for a in self.antialias if a != 1],
        }
        if self.only is None:
            grid = [Setting(m, s, f, shadow_filter=sf) for sf in self.shadow_filters for f in self.shadow_frusta
                    for s in self.supersampling for m in self.shadow_map_sizes]
            grid += [s for knob in KNOBS for s in variations[knob]]
        else:
            grid = [base, *variations[self.only]]
        grid = list(dict.fromkeys(grid))
        return grid + [self.reference_setting] * (self.reference_setting not in grid)


def supersampled_sequence(sequence: SceneSequence, factor: int) -> SceneSequence:
    """``sequence`` drawn at ``factor`` times its resolution, pixel centres kept (module docstring)."""
    if factor == 1:
        return sequence
    S = np.array([[factor, 0, (factor - 1) / 2], [0, factor, (factor - 1) / 2], [0, 0, 1.0]])
    views = tuple(replace(v, camera=replace(v.camera, K=S @ v.camera.K)) for v in sequence.views)
    h, w = sequence.image_size
    return replace(sequence, image_size=(factor * h, factor * w), views=views)


def render_views(renderer: render.SceneRenderer, sequence: SceneSequence, painting: np.ndarray,
                 factor: int = 1) -> tuple[torch.Tensor, torch.Tensor]:
    """The views and masks of ``sequence`` at its own size, drawn at ``factor`` times that size.

    Args:
        renderer: a renderer of size ``factor * sequence.image_size``.
        painting: ``(H, W, 3)`` uint8 at ``sequence.image_size``; upsampled bilinearly for ``factor > 1``.

    Returns:
        views ``(V, 3, H, W)`` float32 in [0, 1] on the 8-bit grid (each ``factor x factor`` block
        averaged in linear light, then re-encoded to sRGB and rounded as the renderer does), and
        masks ``(V, 1, H, W)`` float32, 1 where any pixel of the block does not see the painting.
    """
    if factor > 1:
        up = F.interpolate(torch.from_numpy(painting).permute(2, 0, 1)[None].double(), scale_factor=factor,
                           mode="bilinear", align_corners=False)
        painting = up[0].permute(1, 2, 0).round().clamp(0, 255).to(torch.uint8).numpy()
    rendered = renderer.render(supersampled_sequence(sequence, factor), painting)
    views = torch.from_numpy(rendered.views).permute(0, 3, 1, 2).double() / 255
    masks = torch.from_numpy(rendered.masks).unsqueeze(1).double()
    if factor > 1:
        views = linear_to_srgb(F.avg_pool2d(srgb_to_linear(views), factor))
        views = (views * 255).round().clamp(0, 255) / 255
        masks = F.max_pool2d(masks, factor)
    return views.float(), masks.float()


def _dataset(settings: SweepSettings, size: tuple[int, int]) -> SidarDataset:
    extra = {} if settings.n_views is None else {"n_views": settings.n_views}
    config = load_config(settings.preset, **{**settings.overrides, **extra}, image_size=size)
    return SidarDataset(None, config, seed=settings.seed)


def _measure_setting(dataset: SidarDataset, setting: Setting, scenes: int) -> tuple[list[float], list[torch.Tensor]]:
    """Seconds per sequence and the views of scenes ``0 .. scenes - 1`` (one warm-up first)."""
    h, w = dataset.config.image_size
    factor = setting.supersampling
    render_settings = replace(RenderSettings.from_config(dataset.config), image_size=(factor * h, factor * w),
                              shadow_map_size=setting.shadow_map_size, shadow_frustum=setting.shadow_frustum,
                              mesh_error_px=setting.mesh_error_px, texture_filter=setting.texture_filter,
                              shadow_filter=setting.shadow_filter, antialias=setting.antialias)
    renderer = render.SceneRenderer(render_settings)
    try:
        seconds, views = [], []
        for index in [_WARMUP_INDEX, *range(scenes)]:
            sequence = dataset.scene(index)
            painting = dataset.source.painting(index % len(dataset.source), (h, w))
            start = time.process_time()
            images, _ = render_views(renderer, sequence, painting, factor)
            if index != _WARMUP_INDEX:
                seconds.append(time.process_time() - start)
                views.append(images)
        return seconds, views
    finally:
        renderer.close()  # large shadow maps and buffers: free them before the next setting


def residual_row(size: tuple[int, int], factor: int, samples: int, seed: int) -> dict[str, Any]:
    """Warp residual (pixels) of ``samples`` ambient, occluder-free speckle samples at ``size``,
    drawn with supersampling ``factor`` (shadow maps play no part: no lights)."""
    config = load_config("ambient", image_size=size, n_views=4)
    dataset = SidarDataset(speckle_paintings(samples, size, seed), config, seed=seed)
    renderer = render.SceneRenderer(replace(RenderSettings.from_config(config),
                                            image_size=(factor * size[0], factor * size[1])))
    lengths = []
    try:
        for index in range(samples):
            sequence = dataset.scene(index)
            views, masks = render_views(renderer, sequence, dataset.source.painting(index, size), factor)
            for pair in warp_residuals(views, masks, sequence_homographies(sequence)[0]):
                lengths.append(np.linalg.norm(pair.displacements, axis=1))
    finally:
        renderer.close()
    if not sum(map(len, lengths)):
        raise ValueError(f"size {size}: no textured patch seen by two views; use a larger size")
    lengths = np.concatenate(lengths)
    return {"median_px": float(np.median(lengths)), "max_px": float(lengths.max()), "patches": len(lengths)}


def pareto_front(rows: list[dict[str, Any]]) -> list[int]:
    """Indices of the rows no other row dominates (``ms_per_view`` lower is better, ``image_psnr_db``
    higher is better; rows with an infinite PSNR, the reference, are left out)."""
    finite = [k for k, r in enumerate(rows) if math.isfinite(r["image_psnr_db"])]

    def dominates(a: dict[str, Any], b: dict[str, Any]) -> bool:
        return (a["ms_per_view"] <= b["ms_per_view"] and a["image_psnr_db"] >= b["image_psnr_db"]
                and (a["ms_per_view"] < b["ms_per_view"] or a["image_psnr_db"] > b["image_psnr_db"]))

    return [k for k in finite if not any(dominates(rows[j], rows[k]) for j in finite if j != k)]


def run_sweep(settings: SweepSettings, log: Callable[[str], None] = print) -> dict[str, Any]:
    """Every measurement, as plain data (see :func:`format_report`); ``log`` gets progress lines."""
    start, load_start = time.perf_counter(), os.getloadavg()[0]
    rows, residuals, labels = [], [], []
    with one_thread():
        for size in settings.sizes:
            label = size_label(size)
            dataset = _dataset(settings, size)
            measured = {}
            ref = settings.reference_setting
            for setting in [ref] + [s for s in settings.settings() if s != ref]:
                measured[setting] = _measure_setting(dataset, setting, settings.scenes)
                log(f"{label}, {setting.label()}: done ({time.perf_counter() - start:.0f} s)")
            reference = torch.stack([v for views in measured[ref][1] for v in views])
            size_rows = []
            for setting in settings.settings():
                seconds, views = measured[setting]
                size_rows.append({
                    "size": label, "shadow_map_size": setting.shadow_map_size, "supersampling": setting.supersampling,
                    "shadow_frustum": setting.shadow_frustum, "mesh_detail": setting.mesh_detail,
                    "texture_filter": setting.texture_filter, "shadow_filter": setting.shadow_filter,
                    "antialias": setting.antialias,
                    "label": setting.label(), "reference": setting == ref,
                    "ms_per_view": 1e3 * statistics.median(seconds) / dataset.config.n_views,
                    "image_psnr_db": psnr(torch.stack([v for vs in views for v in vs]), reference)})
            for k in pareto_front(size_rows):
                size_rows[k]["pareto"] = True
            rows += [{"pareto": False, **r} for r in size_rows]
            for factor in sorted(set(settings.supersampling) | {settings.reference[1]}):
                residuals.append({"size": label, "supersampling": factor,
                                  **residual_row(size, factor, settings.residual_samples, settings.seed)})
            labels.append(label_row(size, settings.label_samples, settings.seed))
            log(f"{label}: residuals and label done ({time.perf_counter() - start:.0f} s)")
    return {"settings": asdict(settings), "views_per_scene": dataset.config.n_views, "rows": rows,
            "residuals": residuals, "labels": labels, "load_start": load_start, "load_end": os.getloadavg()[0],
            "cpus": os.cpu_count(), "seconds": time.perf_counter() - start}


def _db(value: float) -> str:
    return "inf (reference)" if math.isinf(value) else f"{value:.2f}"


def format_report(report: dict[str, Any]) -> str:
    """The sweep as markdown: the speed-against-error table, residuals and label PSNR."""
    s = report["settings"]
    ref = (f"shadow map {s['reference'][0]} with fitted frusta, {s['reference'][1]}x{s['reference'][1]} supersampling, "
           "finest meshes, trilinear filtering")
    lines = [f"Speed against error: '{s['preset']}' preset, {s['scenes']} scenes of {report['views_per_scene']} "
             f"views per setting; image PSNR against the reference render ({ref}) at the same size. "
             "* = Pareto-optimal at its size.", "",
             "| size (H x W) | shadow map | frustum | shadow filter | supersampling | meshes | texture | MSAA "
             "| ms per view | image PSNR (dB) | Pareto |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in report["rows"]:
        lines.append(f"| {r['size']} | {r['shadow_map_size']} | {r['shadow_frustum']} | {r['shadow_filter']} "
                     f"| {r['supersampling']}x "
                     f"| {r['mesh_detail']} | {r['texture_filter']} | {r['antialias']}x | {r['ms_per_view']:.1f} "
                     f"| {_db(r['image_psnr_db'])} | {'*' if r['pareto'] else ''} |")
    lines += ["", "Warp residual (ambient speckle scenes, 4 views; shadow maps play no part):", "",
              "| size (H x W) | supersampling | patches | median px | max px |", "|---|---|---|---|---|"]
    for r in report["residuals"]:
        lines.append(f"| {r['size']} | {r['supersampling']}x | {r['patches']} | {r['median_px']:.4f} "
                     f"| {r['max_px']:.4f} |")
    lines += ["", "| label size (H x W) | samples | worst label PSNR (dB) |", "|---|---|---|"]
    for r in report["labels"]:
        value = "inf (identical)" if math.isinf(r["min_psnr_db"]) else f"{r['min_psnr_db']:.1f}"
        lines.append(f"| {r['size']} | {r['samples']} | {value} |")
    lines += ["", f"Measured in {report['seconds']:.0f} s on {report['cpus']} CPUs (load average "
              f"{report['load_start']:.1f} at the start, {report['load_end']:.1f} at the end)."]
    return "\n".join(lines)


_COLOURS = [(31, 119, 180), (214, 39, 40), (44, 160, 44), (148, 103, 189), (255, 127, 14), (23, 190, 207)]


def plot_front(report: dict[str, Any], path: str | os.PathLike) -> None:
    """Scatter of time per view (x, log scale) against image PSNR (y), one colour per size, each
    point labelled with :meth:`Setting.label`; Pareto-optimal points filled and joined."""
    from PIL import Image, ImageDraw

    rows = [r for r in report["rows"] if math.isfinite(r["image_psnr_db"])]
    width, height, left, right, top, bottom = 900, 600, 70, 30, 40, 60
    image = Image.new("RGB", (width, height), "white")
    draw = ImageDraw.Draw(image)
    if not rows:
        image.save(path)
        return
    xs = [math.log10(r["ms_per_view"]) for r in rows]
    ys = [r["image_psnr_db"] for r in rows]
    x0, x1 = min(xs) - 0.05, max(xs) + 0.05
    y0, y1 = math.floor(min(ys)) - 1, math.ceil(max(ys)) + 1

    def at(x: float, y: float) -> tuple[float, float]:
        return (left + (x - x0) / (x1 - x0) * (width - left - right),
                height - bottom - (y - y0) / (y1 - y0) * (height - top - bottom))

    draw.rectangle([left, top, width - right, height - bottom], outline="black")
    step = max(1, round((y1 - y0) / 10))
    for y in range(int(y0), int(y1) + 1, step):
        px, py = at(x0, y)
        draw.line([px - 4, py, px, py], fill="black")
        draw.text((px - 30, py - 6), f"{y}", fill="black")
    for decade in range(math.floor(x0), math.ceil(x1) + 1):
        for m in (1, 2, 5):
            x = decade + math.log10(m)
            if x0 <= x <= x1:
                px, py = at(x, y0)
                draw.line([px, py, px, py + 4], fill="black")
                draw.text((px - 10, py + 8), f"{10 ** x:g}", fill="black")
    draw.text((width / 2 - 120, height - 25), "time per view, ms (log scale, per core)", fill="black")
    draw.text((5, 12), "image PSNR against the reference render, dB", fill="black")
    for k, size in enumerate(dict.fromkeys(r["size"] for r in rows)):
        colour = _COLOURS[k % len(_COLOURS)]
        mine = [r for r in rows if r["size"] == size]
        front = sorted((r for r in mine if r["pareto"]), key=lambda r: r["ms_per_view"])
        draw.line([at(math.log10(r["ms_per_view"]), r["image_psnr_db"]) for r in front], fill=colour, width=2)
        for r in mine:
            px, py = at(math.log10(r["ms_per_view"]), r["image_psnr_db"])
            draw.ellipse([px - 5, py - 5, px + 5, py + 5], outline=colour, width=2,
                         fill=colour if r["pareto"] else "white")
            draw.text((px + 7, py - 12), r["label"], fill=colour)
        draw.text((width - right - 260, top + 10 + 16 * k), f"{size} (filled: Pareto-optimal)", fill=colour)
    draw.text((width - right - 260, top + 10 + 16 * (k + 1)), "labels: shadow map / supersampling,", fill="black")
    draw.text((width - right - 260, top + 26 + 16 * (k + 1)), "fit: fitted frusta, mesh: auto detail", fill="black")
    image.save(path)


def write_outputs(report: dict[str, Any], out_dir: str | os.PathLike) -> dict[str, Path]:
    """Write ``sweep.md``, ``sweep.json`` and ``sweep.png`` into ``out_dir``; returns their paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = {"md": out / "sweep.md", "json": out / "sweep.json", "png": out / "sweep.png"}
    paths["md"].write_text(format_report(report) + "\n")
    paths["json"].write_text(json.dumps(report, indent=2, default=lambda v: str(v)) + "\n")
    plot_front(report, paths["png"])
    return paths


def _map_and_factor(text: str) -> tuple[int, int]:
    """``"4096x1"`` -> ``(4096, 1)``.

    Raises:
        ValueError: ``text`` is not two positive integers joined by ``x``.
    """
    parts = text.lower().split("x")
    if len(parts) != 2 or not all(p.isdigit() and int(p) > 0 for p in parts):
        raise ValueError(f"--reference: expected MAPxS such as 4096x1, got {text!r}")
    return int(parts[0]), int(parts[1])


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``python -m benchmarks.sweep``; parsing it runs nothing."""
    parser = argparse.ArgumentParser(
        prog="python -m benchmarks.sweep",
        description="For output sizes 192x256 and 384x512 (H x W), shadow maps of 256 to 4096 texels, cone and fitted "
                    "shadow frusta and 1x / 2x supersampling, and from a base setting mesh detail, texture filter, "
                    "shadow filter and multisample antialiasing: time per view (median CPU time over the same scenes "
                    "of the preset, this process) "
                    "against image PSNR versus a reference render (4096 shadow maps, fitted frusta, 2x supersampling, "
                    "finest meshes); warp residual and label PSNR per size. Prints the table and writes sweep.md, "
                    "sweep.json and sweep.png (Pareto front) into --out-dir. About ten minutes on 2 cores.")
    parser.add_argument("--quick", action="store_true",
                        help="192x256, shadow maps 256 and 1024 against a 2048 reference, 3 scenes of 3 views")
    parser.add_argument("--scenes", type=int, default=None, help="scenes per setting (default 6, quick 3)")
    parser.add_argument("--config", default=DEFAULT_PRESET,
                        help=f"preset name or YAML path the scenes come from (default {DEFAULT_PRESET})")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="override a config field of the scenes (repeatable, value read as YAML), e.g. "
                             "--set n_occluders=[1,3]; image_size and the swept knobs come from the sweep")
    parser.add_argument("--supersampling", type=int, nargs="+", default=None, metavar="S",
                        help="supersampling factors of the grid (default 1 2)")
    parser.add_argument("--reference", default=None, metavar="MAPxS",
                        help="shadow map and supersampling of the reference (default 4096x2); 4096x1 measures the "
                             "shadow knobs alone, without the aliasing that dominates the error against a "
                             "supersampled reference")
    parser.add_argument("--only", choices=KNOBS, default=None,
                        help="measure only the base setting, this knob's variations and the reference")
    parser.add_argument("--sizes", nargs="+", type=parse_size, default=None, metavar="HxW",
                        help="output sizes (default 192x256 384x512; quick 192x256)")
    parser.add_argument("--out-dir", default="out", help="output folder (default out)")
    return parser


def main(argv: list[str] | None = None) -> None:
    args = build_parser().parse_args(argv)
    try:
        changes = {"preset": args.config, "overrides": parse_set(args.set),
                   **({"scenes": args.scenes} if args.scenes is not None else {}),
                   **({"supersampling": tuple(args.supersampling)} if args.supersampling else {}),
                   **({"reference": _map_and_factor(args.reference)} if args.reference else {}),
                   **({"only": args.only} if args.only else {}),
                   **({"sizes": tuple(args.sizes)} if args.sizes else {})}
        settings = (SweepSettings.quick if args.quick else SweepSettings)(**changes)
    except (ValueError, FileNotFoundError) as error:
        raise SystemExit(f"sweep: {error}") from error
    report = run_sweep(settings, log=lambda line: print(line, file=sys.stderr))
    print(format_report(report))
    paths = write_outputs(report, args.out_dir)
    print(f"wrote {paths['md']}, {paths['json']} and {paths['png']}", file=sys.stderr)


if __name__ == "__main__":
    main()
