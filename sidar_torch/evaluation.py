"""Score an estimator on a test set: ``sidar_torch.evaluate(estimator, testset="homography-v1")``
(``python -m sidar_torch evaluate``).

Homography sets (``task: homography``): an estimator maps two views, ``(H, W, 3)`` uint8 RGB numpy
arrays ``(source, target)``, to a ``(3, 3)`` homography from source pixels to target pixels in the
package's convention (Kornia's and OpenCV's: the centre of the top-left pixel at ``(0, 0)``), or
``None`` for a failure. The pairs are view 0 (fronto-parallel, showing exactly the painting) to each
other view of every sequence. Per pair:

- corner error: the mean distance (target pixels) between the four outer corners of the source
  image (``(-0.5, -0.5)``, ``(W - 0.5, -0.5)``, ... ; the paper's ``(0, 0)``, ``(W - 1, 0)``, ...)
  mapped by the estimate and by the true homography; MACE is its mean over pairs;
- success at 1, 3 and 10 px: corner error at most that;
- a failure (``None``, a non-finite or singular matrix) is scored as the identity (so that MACE
  compares across estimators that fail on different pairs) and counted in ``failures``;
- the estimator's wall time (median over pairs).

Broken down by category (the set's artifact kinds) and by difficulty: ``tilt_deg`` (the angle
between the two cameras' optical axes; unknown for the paper's own data, which has no cameras),
``overlap`` (the fraction of the source image that lands inside the target image), ``occluded``
(the fraction of the painting hidden in the two views, their mean) and ``shadowed`` (the mean
shadow mask on the visible painting of the two views, where the set has shadow masks).

Shadow-removal sets (``task: shadow-removal``): an estimator maps a view ``(H, W, 3)`` uint8 to its
shadow-free version ``(H, W, 3)`` uint8. The score is the RMSE in CIELAB (``kornia.color.rgb_to_lab``,
over all pixels of the set pooled) inside the shadow region (shadow mask >= :data:`SHADOW_THRESHOLD`),
outside it, and over the whole image, as ISTD papers report it.

A named set is rendered once into a cache folder (``cache``; without one, a temporary folder deleted
afterwards) and checked against its recorded digests; a folder is read as it is: an export of a
test set (one export per category), one export, or a folder of the SIDAR paper's own sequences.
"""

from __future__ import annotations

import math
import platform
import tempfile
import time
from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import kornia
import numpy as np
import torch

from .baselines import Estimator, resolve_estimator
from .geometry import corner_pixels
from .io import ExportedDataset
from .io.layout import MANIFEST
from .testsets import available_testsets, export_testset, load_testset

__all__ = ["SHADOW_THRESHOLD", "SUCCESS_PX", "corner_error", "evaluate", "format_table"]

SUCCESS_PX = (1, 3, 10)
"""Corner errors (pixels) a pair must stay within to count as a success at that threshold."""

SHADOW_THRESHOLD = 0.1
"""Shadow mask value from which a pixel is in the shadow region (a tenth of the direct light blocked)."""

BINS = {
    "tilt_deg": (0.0, 20.0, 40.0, 60.0, 180.0),
    "overlap": (0.0, 0.5, 0.75, 0.9, 1.0),
    "occluded": (0.0, 0.01, 0.1, 0.3, 1.0),
    "shadowed": (0.0, 0.01, 0.05, 0.15, 1.0),
}
"""Difficulty measure -> bin edges; a bin holds ``[a, b)``, the last one ``[a, b]``."""


def corner_error(H: np.ndarray | None, H_true: np.ndarray, image_size: tuple[int, int]) -> float:
    """Mean distance (pixels) between the source image's four outer corners mapped by ``H`` and by
    ``H_true`` (both ``(3, 3)``, source to target pixels); ``image_size = (H, W)`` of the source view.
    ``H = None`` is scored as the identity."""
    corners = np.c_[corner_pixels(image_size), np.ones(4)]
    mapped = [corners @ np.asarray(np.eye(3) if M is None else M, np.float64).T for M in (H, H_true)]
    estimate, truth = (m[:, :2] / m[:, 2:] for m in mapped)
    return float(np.linalg.norm(estimate - truth, axis=1).mean())


@dataclass
class _Category:
    name: str
    dataset: ExportedDataset


def evaluate(estimator: str | Estimator, testset: str | Path = "homography-v1", limit: int | None = None,
             cache: str | Path | None = None, progress: bool = False) -> dict[str, Any]:
    """Score ``estimator`` on ``testset`` (see the module docstring for the metrics).

    Args:
        estimator: a callable (see the module docstring), the name of a shipped baseline
            (:data:`sidar_torch.baselines.ESTIMATORS`) or ``"module:function"``.
        testset: a shipped set's name (:func:`sidar_torch.testsets.available_testsets`) or a folder.
        limit: score only the first ``limit`` pairs (views for shadow removal), taken in turn from
            each category; for a named set only the sequences they need are rendered.
        cache: for a named set, the folder it is rendered into (kept, and reused by later calls);
            ``None``: a temporary folder, deleted afterwards.
        progress: print the rendering's progress on stderr.

    Returns:
        ``{"set", "task", "estimator", "pairs", "mace", "median_error", "success": {"1", "3", "10"},
        "failures", "median_seconds", "by_category": {name: {...}}, "by_difficulty": {measure:
        {bin: {...}}}, "cache", "digests", "machine"}`` for homography sets (errors in pixels,
        success as fractions, times in seconds); for shadow-removal sets ``"images"`` and ``"rmse":
        {"shadow", "non_shadow", "all"}`` instead of the pair metrics.

    Raises:
        ValueError: an unknown set or estimator, ``limit < 1``, an estimator returning something that is
            not ``None`` nor a 3 x 3 matrix (an image of the view's shape for shadow removal).
        ImportError: a baseline that needs OpenCV without it (the message names the extra).
    """
    if limit is not None and (isinstance(limit, bool) or not isinstance(limit, int) or limit < 1):
        raise ValueError(f"limit: expected an integer >= 1 or None, got {limit!r}")
    name, function = resolve_estimator(estimator) if isinstance(estimator, str) else (_name(estimator), estimator)
    with ExitStack() as stack:
        set_name, task, categories, cache_note, digests = _open(testset, limit, cache, progress, stack)
        score = _score_shadow_removal if task == "shadow-removal" else _score_homographies
        result = {"set": set_name, "task": task, "estimator": name, **score(function, categories, limit)}
    return {**result, "cache": cache_note, "digests": digests,
            "machine": f"{platform.machine()}, {platform.system()} {platform.release()}, Python {platform.python_version()}"}


def _name(function: Callable) -> str:
    return f"{getattr(function, '__module__', '?')}:{getattr(function, '__qualname__', type(function).__name__)}"


def _open(testset: str | Path, limit: int | None, cache: str | Path | None, progress: bool,
          stack: ExitStack) -> tuple[str, str, list[_Category], str, dict[str, Any] | None]:
    """``(set name, task, categories, where the data is, digest check)`` of ``testset``."""
    if isinstance(testset, str) and testset in available_testsets():
        definition = load_testset(testset)
        sequences = None
        if limit is not None:
            per_round = sum(category.config["n_views"] - (definition.task == "homography")
                            for category in definition.categories)
            sequences = math.ceil(limit / per_round)
        folder = Path(cache) if cache is not None else Path(stack.enter_context(tempfile.TemporaryDirectory(
            prefix=f"sidar-{testset}-")))
        check = export_testset(definition, folder, sequences, progress)
        note = str(folder) if cache is not None else f"{folder} (temporary, deleted afterwards)"
        digests = {"matches": check.matches, "checked": check.checked, "differing": list(check.differing[:20]),
                   "summary": check.summary()}
        categories = [_Category(c.name, ExportedDataset(folder / c.name)) for c in definition.categories]
        return testset, definition.task, categories, note, digests
    folder = Path(testset)
    if not folder.is_dir():
        raise ValueError(f"testset: expected one of {available_testsets()} or a folder, got {str(testset)!r}")
    exports = sorted(p for p in folder.iterdir() if (p / MANIFEST).is_file())
    categories = ([_Category(p.name, ExportedDataset(p)) for p in exports] if exports and not (folder / MANIFEST).exists()
                  else [_Category(folder.name, ExportedDataset(folder))])
    task = "shadow-removal" if all(c.dataset.config.get("shadow_free_output") for c in categories) else "homography"
    return str(folder), task, categories, f"{folder} (read as it is)", None


def _in_turn(categories: list[_Category]):
    """``(category, item)`` of every sequence, the ``k``-th of each category in turn, ``k = 0, 1, ...``."""
    for k in range(max(len(c.dataset) for c in categories)):
        for category in categories:
            if k < len(category.dataset):
                yield category.name, category.dataset[k]


def _uint8(image: torch.Tensor) -> np.ndarray:
    """``(3, H, W)`` float in [0, 1] (8-bit levels) -> ``(H, W, 3)`` uint8."""
    return (image.permute(1, 2, 0) * 255).round().to(torch.uint8).numpy()


def _score_homographies(estimator: Estimator, categories: list[_Category], limit: int | None) -> dict[str, Any]:
    rows: list[dict[str, Any]] = []
    for category, sample in _in_turn(categories):
        for j in range(1, len(sample["images"])):
            if limit is not None and len(rows) == limit:
                return _homography_summary(rows)
            rows.append({"category": category, **_score_pair(estimator, sample, 0, j)})
    return _homography_summary(rows)


def _score_pair(estimator: Estimator, sample: dict[str, Any], i: int, j: int) -> dict[str, Any]:
    """One pair's corner error, failure, time and difficulty measures."""
    source, target = _uint8(sample["images"][i]), _uint8(sample["images"][j])
    start = time.perf_counter()
    H = estimator(source, target)
    seconds = time.perf_counter() - start
    H = _checked(H, estimator)
    H_true = sample["homographies"][i, j].double().numpy()
    size = source.shape[:2]
    return {"error": corner_error(H, H_true, size), "failed": H is None, "seconds": seconds,
            **_difficulty(sample, i, j, size)}


def _checked(H: Any, estimator: Estimator) -> np.ndarray | None:
    """The estimate as ``(3, 3)`` float64, or ``None`` for a failure (``None``, non-finite, singular)."""
    if H is None:
        return None
    H = np.asarray(H.detach().cpu() if isinstance(H, torch.Tensor) else H, dtype=np.float64)
    if H.shape != (3, 3):
        raise ValueError(f"estimator {_name(estimator)}: expected a (3, 3) homography or None, got shape {H.shape}")
    if not np.isfinite(H).all() or abs(np.linalg.det(H / np.abs(H).max())) < 1e-12:
        return None
    return H


def _difficulty(sample: dict[str, Any], i: int, j: int, size: tuple[int, int]) -> dict[str, float]:
    """The pair's difficulty measures (see the module docstring); NaN where the data cannot say."""
    R = sample["R"].double().numpy()
    axes = R[[i, j], 2]  # each camera's optical axis in world coordinates (row 2 of world-to-camera R)
    tilt = math.degrees(math.acos(float(np.clip(axes[0] @ axes[1], -1, 1)))) if np.isfinite(axes).all() else math.nan
    H = sample["homographies"].double().numpy()
    h, w = size
    v, u = np.mgrid[0:h:4, 0:w:4]
    grid = np.c_[u.ravel(), v.ravel()].astype(np.float64)
    overlap = float(_inside(_mapped(H[i, j], grid), size).mean())
    masks = sample["masks"][:, 0].numpy()[:, ::4, ::4].reshape(len(H), -1)
    shadows = sample.get("shadow_masks")
    hidden, shadowed = [], []
    for view in (i, j):
        on_painting = _inside(_mapped(H[view, 0], grid), size)  # view 0 shows exactly the painting
        hidden.append(float(masks[view][on_painting].mean()) if on_painting.any() else 1.0)
        if shadows is not None:
            visible = on_painting & (masks[view] == 0)
            values = shadows[view, 0].numpy()[::4, ::4].ravel()[visible]
            shadowed.append(float(values.mean()) if visible.any() else 0.0)
    return {"tilt_deg": tilt, "overlap": overlap, "occluded": float(np.mean(hidden)),
            "shadowed": float(np.mean(shadowed)) if shadowed else math.nan}


def _mapped(H: np.ndarray, points: np.ndarray) -> np.ndarray:
    mapped = np.c_[points, np.ones(len(points))] @ H.T
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(mapped[:, 2:] > 0, mapped[:, :2] / mapped[:, 2:], np.inf)


def _inside(points: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    h, w = size
    return (points[:, 0] >= -0.5) & (points[:, 0] <= w - 0.5) & (points[:, 1] >= -0.5) & (points[:, 1] <= h - 0.5)


def _pair_metrics(rows: list[dict[str, Any]]) -> dict[str, Any]:
    errors = np.array([row["error"] for row in rows])
    if not len(errors):
        return {"pairs": 0}
    return {"pairs": len(rows), "mace": float(errors.mean()), "median_error": float(np.median(errors)),
            "success": {str(px): float((errors <= px).mean()) for px in SUCCESS_PX},
            "failures": sum(row["failed"] for row in rows)}


def _homography_summary(rows: list[dict[str, Any]]) -> dict[str, Any]:
    categories = list(dict.fromkeys(row["category"] for row in rows))
    by_difficulty = {}
    for measure, edges in BINS.items():
        bins = {}
        for k, (low, high) in enumerate(zip(edges[:-1], edges[1:])):
            last = k == len(edges) - 2
            inside = [row for row in rows if low <= row[measure] < high or (last and row[measure] == high)]
            if inside:
                bins[f"[{low:g}, {high:g}{']' if last else ')'}"] = _pair_metrics(inside)
        unknown = [row for row in rows if math.isnan(row[measure])]
        if unknown:
            bins["unknown"] = _pair_metrics(unknown)
        by_difficulty[measure] = bins
    return {**_pair_metrics(rows), "median_seconds": float(np.median([row["seconds"] for row in rows])) if rows else None,
            "by_category": {name: _pair_metrics([row for row in rows if row["category"] == name]) for name in categories},
            "by_difficulty": by_difficulty}


def _lab(image: np.ndarray) -> np.ndarray:
    """``(H, W, 3)`` uint8 sRGB -> ``(H, W, 3)`` float64 CIELAB (L in [0, 100])."""
    tensor = torch.from_numpy(image).permute(2, 0, 1).float()[None] / 255
    return kornia.color.rgb_to_lab(tensor)[0].permute(1, 2, 0).double().numpy()


def _score_shadow_removal(estimator: Estimator, categories: list[_Category], limit: int | None) -> dict[str, Any]:
    sums: dict[str, dict[str, list[float]]] = {}
    images, seconds = 0, []
    for category, sample in _in_turn(categories):
        for v in range(len(sample["images"])):
            if limit is not None and images == limit:
                break
            view, target = _uint8(sample["images"][v]), _uint8(sample["shadow_free"][v])
            start = time.perf_counter()
            out = estimator(view)
            seconds.append(time.perf_counter() - start)
            out = np.asarray(out)
            if out.shape != view.shape or out.dtype != np.uint8:
                raise ValueError(f"estimator {_name(estimator)}: expected a {view.shape} uint8 image, got "
                                 f"{out.shape} {out.dtype}")
            squared = ((_lab(out) - _lab(target)) ** 2).sum(-1)
            shadow = sample["shadow_masks"][v, 0].numpy() >= SHADOW_THRESHOLD
            for key in (category, "(all)"):
                totals = sums.setdefault(key, {"shadow": [0.0, 0], "non_shadow": [0.0, 0], "all": [0.0, 0]})
                for region, where in (("shadow", shadow), ("non_shadow", ~shadow), ("all", np.ones_like(shadow))):
                    totals[region][0] += float(squared[where].sum())
                    totals[region][1] += int(where.sum())
            images += 1

    def rmse(totals: dict[str, list[float]]) -> dict[str, float]:
        return {region: math.sqrt(s / n) if n else math.nan for region, (s, n) in totals.items()}

    return {"images": images, "rmse": rmse(sums["(all)"]), "median_seconds": float(np.median(seconds)),
            "by_category": {name: {"rmse": rmse(totals)} for name, totals in sums.items() if name != "(all)"}}


def format_table(result: dict[str, Any]) -> str:
    """The result of :func:`evaluate` as text: a summary line and markdown tables by category and difficulty."""
    if result["task"] == "shadow-removal":
        lines = [f"{result['set']}: {result['images']} views, estimator {result['estimator']}, "
                 f"median {result['median_seconds'] * 1e3:.1f} ms per view; RMSE in CIELAB (shadow mask >= "
                 f"{SHADOW_THRESHOLD}: shadow region)", "", "| category | shadow | non-shadow | all |", "|---|---|---|---|"]
        for name, metrics in [*result["by_category"].items(), ("(all)", {"rmse": result["rmse"]})]:
            rmse = metrics["rmse"]
            lines.append(f"| {name} | {rmse['shadow']:.2f} | {rmse['non_shadow']:.2f} | {rmse['all']:.2f} |")
        return "\n".join(lines)
    lines = [f"{result['set']}: {result['pairs']} pairs, estimator {result['estimator']}, "
             f"median {result['median_seconds'] * 1e3:.1f} ms per pair (corner errors in pixels; a failure "
             f"scores as the identity)", "",
             "| category | pairs | MACE | median | <= 1 px | <= 3 px | <= 10 px | failures |",
             "|---|---|---|---|---|---|---|---|"]
    lines += [_row(name, metrics) for name, metrics in result["by_category"].items()]
    lines += [_row("**all**", result), "", "| difficulty | bin | pairs | MACE | median | <= 1 px | <= 3 px | <= 10 px | failures |",
              "|---|---|---|---|---|---|---|---|---|"]
    for measure, bins in result["by_difficulty"].items():
        lines += [_row(f"{measure} | {label}", metrics) for label, metrics in bins.items()]
    return "\n".join(lines)


def _row(label: str, metrics: dict[str, Any]) -> str:
    success = " | ".join(f"{100 * metrics['success'][str(px)]:.0f} %" for px in SUCCESS_PX)
    return (f"| {label} | {metrics['pairs']} | {metrics['mace']:.2f} | {metrics['median_error']:.2f} | {success} | "
            f"{metrics['failures']} |")
