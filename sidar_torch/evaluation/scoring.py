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
- a failure is scored as the identity (so that MACE compares across estimators that fail on
  different pairs) and counted in ``failures``: the estimator returned ``None``, a matrix with a
  non-finite entry, a singular one (``|det(H / max|H|)| <`` :data:`SINGULAR_DET`), or one that does
  not map all four corners in front of the target camera (their homogeneous ``w`` of one sign and
  ``|w| >=`` :data:`HORIZON_W` ``|(x, y, w)|``, i.e. each within 1e12 px), or it raised or ran
  past its timeout (below). So every corner error, and MACE, is finite;
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

Each call of the estimator goes through :class:`GuardedEstimator`: an exception it raises is
printed with its traceback on stderr and the pair scored as a failure (a view as left unchanged),
counted in ``errors``; a call that has not returned after ``timeout`` seconds is stopped, scored
the same way and counted in ``timeouts``; the run goes on. An ``ImportError`` or
``FileNotFoundError`` (a missing package or weights file: no pair could be scored) stops the run.

A named set is rendered once into a cache folder (``cache``; without one, a temporary folder deleted
afterwards) and checked against its recorded digests; a folder is read as it is: an export of a
test set (one export per category), one export, or a folder of the SIDAR paper's own sequences.
``limit`` takes pairs (views) one from each category in turn, so that every category is scored.

With ``protocol="patches"`` the pairs of a homography set are those of the patch-pair protocol
(:mod:`sidar_torch.deep_homography.protocol`: a ``patch x patch`` box of view ``i``, the same box of
view ``j`` brought back by ``H_ij`` and moved by a seeded random perturbation of its corners of at most
``rho`` pixels, for every ordered view pair whose two patches show enough painting). The estimator
sees the two patches; the truth is the perturbation; corner errors are at the patch's outer corners.
``warps-v1`` (:class:`sidar_torch.deep_homography.warps.WarpTestSet`), classic 2-D warps of paintings
no shipped network trained on, is generated in memory and checked against its recorded digest.
"""

from __future__ import annotations

import ctypes
import math
import platform
import sys
import tempfile
import threading
import time
import traceback
from contextlib import ExitStack
from dataclasses import dataclass
from itertools import islice
from pathlib import Path
from typing import Any, Callable, Iterable, Iterator

import kornia
import numpy as np
import torch

from .baselines import Estimator, resolve_estimator
from ..deep_homography.protocol import MIN_VISIBLE, PATCH, RHO, cut_pair, draw_pairs
from ..deep_homography.warps import WARPS_V1_SHA256, WarpTestSet
from ..config import as_float
from ..config.numbers import shown
from ..geometry import corner_pixels
from ..io import ExportedDataset
from ..io.layout import MANIFEST
from .testsets import TestSet, available_testsets, export_testset, load_testset

__all__ = ["DEFAULT_TIMEOUT", "HORIZON_W", "SHADOW_THRESHOLD", "SINGULAR_DET", "SUCCESS_PX", "TOTAL", "Call",
           "EstimatorTimeout", "GuardedEstimator", "PROTOCOLS", "checked_timeout", "corner_error", "evaluate",
           "format_table", "score_pair", "testset_names"]

SUCCESS_PX = (1, 3, 10)
"""Corner errors (pixels) a pair must stay within to count as a success at that threshold."""

SINGULAR_DET = 1e-12
"""An estimate ``H`` with ``|det(H / max|H|)|`` below this is singular: a failure."""

HORIZON_W = 1e-12
"""An estimate mapping a source corner to homogeneous ``(x, y, w)`` with ``|w| < HORIZON_W |(x, y, w)|``
(at or near the horizon: further than 1e12 px), or the four corners to ``w`` of both signs (some
behind the camera), is a failure."""

DEFAULT_TIMEOUT = 60.0
"""Seconds one call of an estimator may take before it is stopped and scored as a failure."""

SHADOW_THRESHOLD = 0.1
"""Shadow mask value from which a pixel is in the shadow region (a tenth of the direct light blocked)."""

TOTAL = "**total**"
"""The label of :func:`format_table`'s row over all categories (a set's categories include one named ``all``)."""

PROTOCOLS = ("views", "patches")
"""How a homography set's pairs are made: ``views``, view 0 to each other view, whole; ``patches``, the
patch-pair protocol (:mod:`sidar_torch.deep_homography.protocol`) on every ordered view pair."""

GENERATED = {"warps-v1": WarpTestSet}
"""Test sets generated in memory instead of rendered: name -> the class whose instance holds them."""

BINS = {
    "tilt_deg": (0.0, 20.0, 40.0, 60.0, 180.0),
    "overlap": (0.0, 0.5, 0.75, 0.9, 1.0),
    "occluded": (0.0, 0.01, 0.1, 0.3, 1.0),
    "shadowed": (0.0, 0.01, 0.05, 0.15, 1.0),
}
"""Difficulty measure -> bin edges; a bin holds ``[a, b)``, the last one ``[a, b]``."""


def corner_error(H: np.ndarray | None, H_true: np.ndarray, image_size: tuple[int, int]) -> float:
    """Mean distance (pixels) between the source image's four outer corners mapped by ``H`` and by
    ``H_true`` (both ``(3, 3)``, source to target pixels, at any scale); ``image_size = (H, W)`` of
    the source view. ``H = None`` is scored as the identity. Finite when both map every corner in
    front of the camera (:func:`_in_front`)."""
    mapped = [_mapped_corners(np.eye(3) if M is None else M, image_size) for M in (H, H_true)]
    estimate, truth = (m[:, :2] / m[:, 2:] for m in mapped)
    return float(np.linalg.norm(estimate - truth, axis=1).mean())


def _mapped_corners(H: np.ndarray, image_size: tuple[int, int]) -> np.ndarray:
    """``(4, 3)`` float64: the source image's outer corners mapped by ``H`` scaled to ``max|H| = 1``
    (the same homography, and no overflow for ``1e308 * I``), homogeneous."""
    H = np.asarray(H, np.float64)
    return np.c_[corner_pixels(image_size), np.ones(4)] @ (H / np.abs(H).max()).T


def _in_front(H: np.ndarray, image_size: tuple[int, int]) -> bool:
    """Whether ``H`` (finite, not 0) maps the four corners to homogeneous ``w`` of one sign and each
    at least :data:`HORIZON_W` of its ``|(x, y, w)|``."""
    mapped = _mapped_corners(H, image_size)
    w = mapped[:, 2] * np.sign(mapped[0, 2])
    return bool((w >= HORIZON_W * np.linalg.norm(mapped, axis=1)).all())


class EstimatorTimeout(BaseException):
    """Raised inside a call of an estimator that ran past its timeout, to stop it (a ``BaseException``,
    as ``KeyboardInterrupt``, so that the estimator's own ``except Exception`` does not swallow it)."""


@dataclass(frozen=True)
class Call:
    """One call of an estimator: what it returned (``None`` when it raised or timed out), its wall
    time in seconds, and how it ended: ``"returned"``, ``"raised"`` or ``"timed out"``."""

    value: Any
    seconds: float
    outcome: str


class GuardedEstimator:
    """An estimator called so that no call stops the run: what it raises is reported and scored, a
    call past ``timeout`` seconds is stopped.

    Each call runs in a new daemon thread, and the caller waits for it at most ``timeout`` seconds.
    Past that, :class:`EstimatorTimeout` is raised inside the call (CPython's
    ``PyThreadState_SetAsyncExc``), which stops it at its next Python instruction: a Python loop at
    once; a call inside C (``time.sleep``, an OpenCV or torch kernel) when it returns to Python, and
    until then it runs on in the background (using a core, and the estimator's objects while the
    next calls run). Limits: a C call that holds the GIL and never returns hangs the process (only
    an estimator run in a process of its own could be stopped then); per-thread state
    (``torch.no_grad()``, a CUDA stream, OpenCV's RNG seed) must be set inside the estimator, as the
    baselines do. ``timeout=None`` calls the estimator in the caller's thread, without a limit.

    An ``Exception`` the estimator raises is printed on stderr (one line; the traceback too the first
    time that type and message come) and the call's outcome is ``"raised"``; ``ImportError`` and
    ``FileNotFoundError`` (a missing package or weights file: no call could succeed) and what is not
    an ``Exception`` (``KeyboardInterrupt``, ``SystemExit``) are raised again.

    Args:
        function: the estimator: views (``(H, W, 3)`` uint8) -> its answer.
        name: how messages name it (``"sift"``, ``"my_package.models:estimate"``).
        timeout: seconds, a finite number ``> 0`` (at most ``threading.TIMEOUT_MAX``), or ``None``.

    Raises:
        ValueError: a wrong ``timeout`` (the message names it).
    """

    def __init__(self, function: Estimator, name: str, timeout: float | None = DEFAULT_TIMEOUT):
        self.function, self.name, self.timeout = function, name, checked_timeout(timeout)
        self._reported: set[str] = set()

    def __call__(self, *views: np.ndarray, what: str = "a call") -> Call:
        """The estimator's answer to ``views`` as a :class:`Call`; ``what`` names the pair or view in
        messages (``"clean sequence 3, view 0 -> 2"``)."""
        if self.timeout is None:
            outcome, value, seconds = _called(self.function, views)
        else:
            outcome, value, seconds = _called_in_thread(self.function, views, self.timeout)
        if outcome == "raised":
            if isinstance(value, (ImportError, FileNotFoundError)) or not isinstance(value, Exception):
                raise value
            self._report(value, what)
        elif outcome == "timed out":
            print(f"estimator {self.name}: no answer on {what} after {self.timeout:g} s: stopped, scored as a "
                  f"failure (the limit: --timeout SECONDS, evaluate(timeout=...))", file=sys.stderr)
        return Call(value if outcome == "returned" else None, seconds, outcome)

    def _report(self, error: Exception, what: str) -> None:
        line = f"{type(error).__name__}: {error}"
        print(f"estimator {self.name} raised on {what} (scored as a failure; the run goes on): {line}",
              file=sys.stderr)
        if line not in self._reported:
            self._reported.add(line)
            traceback.print_exception(error, file=sys.stderr)


def checked_timeout(timeout: Any) -> float | None:
    """``timeout`` (seconds) checked: a finite number ``> 0``, at most ``threading.TIMEOUT_MAX``, or ``None``.

    Raises:
        ValueError: anything else (the message starts with ``timeout:``).
    """
    if timeout is None:
        return None
    seconds = as_float("timeout", timeout)
    if not 0 < seconds <= threading.TIMEOUT_MAX:
        raise ValueError(f"timeout: expected seconds > 0 and at most {threading.TIMEOUT_MAX:g}, or None, "
                         f"got {timeout!r}")
    return seconds


def _called(function: Estimator, args: tuple[Any, ...]) -> tuple[str, Any, float]:
    """``("returned", value, seconds)`` or ``("raised", exception, seconds)`` of ``function(*args)``."""
    start = time.perf_counter()
    try:
        return "returned", function(*args), time.perf_counter() - start
    except BaseException as error:  # handed to the caller, which raises again what is no Exception
        return "raised", error, time.perf_counter() - start


def _called_in_thread(function: Estimator, args: tuple[Any, ...], timeout: float) -> tuple[str, Any, float]:
    """:func:`_called` in a daemon thread (interpreter exit does not wait for it), or ``("timed out",
    None, seconds)`` when it has not ended after ``timeout`` seconds (and then it is stopped)."""
    ended: list[tuple[str, Any, float]] = []

    def run() -> None:
        try:
            ended.append(_called(function, args))
        except EstimatorTimeout:  # came after the call had ended: nothing left to stop
            pass

    start = time.perf_counter()
    thread = threading.Thread(target=run, name="sidar_torch estimator", daemon=True)
    thread.start()
    thread.join(timeout)
    if ended:
        return ended[0]
    if thread.is_alive() and not ended:  # (it may have ended meanwhile: then there is nothing to stop)
        ctypes.pythonapi.PyThreadState_SetAsyncExc(ctypes.c_ulong(thread.ident), ctypes.py_object(EstimatorTimeout))
    return "timed out", None, time.perf_counter() - start


def score_pair(estimator: GuardedEstimator, source: np.ndarray, target: np.ndarray, H_true: np.ndarray,
               what: str = "a pair") -> dict[str, Any]:
    """Call ``estimator`` on one pair, check its answer and score it (the module docstring's rules).

    Args:
        estimator: the estimator, guarded (:class:`GuardedEstimator`).
        source, target: ``(H, W, 3)`` uint8 RGB views (their sizes may differ).
        H_true: ``(3, 3)`` float64, source pixels to target pixels.
        what: names the pair in messages.

    Returns:
        ``{"error": corner error (target pixels, finite), "failed": bool, "outcome": "returned",
        "raised" or "timed out", "seconds": the call's wall time}``.

    Raises:
        ValueError: the estimator returned neither ``None`` nor a ``(3, 3)`` real matrix (the message
            names it).
    """
    call = estimator(source, target, what=what)
    size = source.shape[:2]
    H = _checked(call.value, estimator.name, size)
    return {"error": corner_error(H, H_true, size), "failed": H is None, "outcome": call.outcome,
            "seconds": call.seconds}


def _checked(H: Any, name: str, image_size: tuple[int, int]) -> np.ndarray | None:
    """The estimate as ``(3, 3)`` float64, or ``None`` for a failure: ``None``, a non-finite entry,
    singular (:data:`SINGULAR_DET`), a corner not in front (:func:`_in_front`).

    Raises:
        ValueError: ``H`` is neither ``None`` nor a ``(3, 3)`` matrix of real numbers (``name`` named).
    """
    if H is None:
        return None
    try:
        array = np.asarray(H.detach().cpu().double() if isinstance(H, torch.Tensor) else H)
    except (TypeError, ValueError):  # a ragged list, an object NumPy cannot read
        array = np.asarray(None)
    if array.dtype.kind not in "iuf" or array.shape != (3, 3):
        got = f"shape {array.shape}" if array.dtype.kind in "iuf" else f"{type(H).__name__} {shown(H)}"
        raise ValueError(f"estimator {name}: expected a (3, 3) homography or None, got {got}")
    H = array.astype(np.float64)
    if not np.isfinite(H).all() or not H.any():
        return None
    if abs(np.linalg.det(H / np.abs(H).max())) < SINGULAR_DET or not _in_front(H, image_size):
        return None
    return H


def testset_names() -> list[str]:
    """Every test set :func:`evaluate` knows by name: the rendered ones, then the generated ones."""
    return [*available_testsets(), *GENERATED]


def _name(function: Callable) -> str:
    return f"{getattr(function, '__module__', '?')}:{getattr(function, '__qualname__', type(function).__name__)}"


@dataclass
class _Category:
    name: str
    dataset: ExportedDataset


def evaluate(estimator: str | Estimator, testset: str | Path = "homography-v1", limit: int | None = None,
             cache: str | Path | None = None, progress: bool = False,
             timeout: float | None = DEFAULT_TIMEOUT, protocol: str = "views", seed: int = 0, patch: int = PATCH,
             rho: float = RHO) -> dict[str, Any]:
    """Score ``estimator`` on ``testset`` (see the module docstring for the metrics).

    Args:
        estimator: a callable (see the module docstring), the name of a shipped baseline
            (:data:`sidar_torch.evaluation.baselines.ESTIMATORS`) or ``"module:function"``.
        testset: a shipped set's name (:func:`sidar_torch.evaluation.testsets.available_testsets`) or a folder.
        limit: score only ``limit`` pairs (views for shadow removal), taken one from each category in
            turn (round robin: with 5 categories, ``limit=10`` scores 2 of each); for a named set only
            the sequences they need are rendered.
        cache: for a named set, the folder it is rendered into (kept, and reused by later calls);
            ``None``: a temporary folder, deleted afterwards.
        progress: print the rendering's progress on stderr.
        timeout: seconds one call of the estimator may take; past it the call is stopped and scored
            as a failure (:class:`GuardedEstimator` says how, and its limits); ``None``: no limit, the
            estimator called in this thread.
        protocol: one of :data:`PROTOCOLS` (homography sets).
        seed, patch, rho: the patch protocol's seed, box side (pixels) and largest corner perturbation
            per coordinate (pixels); ignored by ``views``.

    Returns:
        ``{"set", "task", "estimator", "timeout", "pairs", "mace", "median_error", "success": {"1",
        "3", "10"}, "failures", "errors", "timeouts", "pair_errors" (each pair's corner error, in the order
        scored: for intervals and paired comparisons), "median_seconds", "by_category": {name: {...}},
        "by_difficulty": {measure: {bin: {...}}}, "protocol": {...}, "cache", "digests", "machine"}`` for
        homography sets
        (errors in pixels, success as fractions, times in seconds; ``failures`` includes ``errors``,
        the calls that raised, and ``timeouts``); for shadow-removal sets ``"images"`` and ``"rmse":
        {"shadow", "non_shadow", "all"}`` instead of the pair metrics.

    Raises:
        ValueError: an unknown set or estimator, a folder that is not an export or holds nothing to
            score, a malformed file in it (named), ``limit < 1``, a wrong ``timeout``, an estimator
            returning something that is not ``None`` nor a 3 x 3 matrix (an image of the view's shape
            for shadow removal).
        ImportError: a baseline that needs OpenCV without it (the message names the extra), a
            ``module:function`` whose module does not import.
    """
    if limit is not None and (isinstance(limit, bool) or not isinstance(limit, int) or limit < 1):
        raise ValueError(f"limit: expected an integer >= 1 or None, got {limit!r}")
    if protocol not in PROTOCOLS:
        raise ValueError(f"protocol: expected one of {PROTOCOLS}, got {protocol!r}")
    name, function = resolve_estimator(estimator) if isinstance(estimator, str) else (_name(estimator), estimator)
    guarded = GuardedEstimator(function, name, timeout)
    with ExitStack() as stack:
        set_name, task, categories, cache_note, digests = _open(testset, limit, cache, progress, stack)
        if protocol == "patches":
            if task != "homography":
                raise ValueError(f"protocol 'patches': expected a homography set, {set_name!r} is a {task} set")
            settings = {"seed": seed, "patch": patch, "rho": rho, "min_visible": MIN_VISIBLE}
            units = islice(_in_turn(_patch_units(c, settings) for c in categories), limit)
            scores = {**_score_patches(guarded, units), "protocol": {"name": protocol, **settings}}
        else:
            units = islice(_in_turn(_units(c, TASKS[task].first_view) for c in categories), limit)
            scores = {**TASKS[task].score(guarded, units), **({"protocol": {"name": protocol}}
                                                              if task == "homography" else {})}
        result = {"set": set_name, "task": task, "estimator": name, "timeout": guarded.timeout, **scores}
    return {**result, "cache": cache_note, "digests": digests,
            "machine": f"{platform.machine()}, {platform.system()} {platform.release()}, Python {platform.python_version()}"}


def _open(testset: str | Path, limit: int | None, cache: str | Path | None, progress: bool,
          stack: ExitStack) -> tuple[str, str, list[_Category], str, dict[str, Any] | None]:
    """``(set name, task, categories, where the data is, digest check)`` of ``testset``.

    Raises:
        ValueError: ``testset`` is neither a set's name nor a folder, the folder is no export (the
            reader's message) or holds nothing to score.
    """
    if isinstance(testset, str) and testset in GENERATED:
        generated = GENERATED[testset]()
        return testset, "homography", [_Category(testset, generated)], "generated in memory", \
            None if limit is not None else _generated_digest(generated)
    if isinstance(testset, str) and testset in available_testsets():
        definition = load_testset(testset)
        sequences = None if limit is None else _sequences_needed(definition, limit)
        folder = Path(cache) if cache is not None else Path(stack.enter_context(tempfile.TemporaryDirectory(
            prefix=f"sidar-{testset}-")))
        check = export_testset(definition, folder, sequences, progress)
        note = str(folder) if cache is not None else f"{folder} (temporary, deleted afterwards)"
        digests = {"matches": check.matches, "checked": check.checked, "differing": list(check.differing[:20]),
                   "summary": check.summary()}
        categories = [_Category(c.name, _read(folder / c.name)) for c in definition.categories]
        return testset, definition.task, categories, note, digests
    folder = Path(testset)
    if not folder.is_dir():
        raise ValueError(f"testset: expected one of {testset_names()} or a folder, got {str(testset)!r}")
    exports = sorted(p for p in folder.iterdir() if (p / MANIFEST).is_file())
    categories = ([_Category(p.name, _read(p)) for p in exports] if exports and not (folder / MANIFEST).exists()
                  else [_Category(folder.name, _read(folder))])
    task = "shadow-removal" if all(c.dataset.config.get("shadow_free_output") for c in categories) else "homography"
    first = TASKS[task].first_view
    if not any(len(c.dataset) and c.dataset.config["n_views"] > first for c in categories):
        raise ValueError(f"testset {str(folder)!r}: nothing to score, no sequence of {first + 1} views or more "
                         f"(exports read: {', '.join(str(c.dataset.path) for c in categories)})")
    return str(folder), task, categories, f"{folder} (read as it is)", None


def _read(folder: Path) -> ExportedDataset:
    """An export (or a paper folder) read with its geometry in float64: the truth as precise as its files
    hold (the paper's ``H_i_j.mat`` texts read in float32 are 15.7 px off near the horizon)."""
    return ExportedDataset(folder, geometry_dtype="float64")


def _generated_digest(generated: WarpTestSet) -> dict[str, Any]:
    """The digest check of a generated set (every sequence generated once more: seconds)."""
    digest = generated.digest()
    return {"matches": digest == WARPS_V1_SHA256, "checked": len(generated), "differing": [],
            "summary": f"its views {'match' if digest == WARPS_V1_SHA256 else 'differ from'} the recorded SHA-256 "
                       f"({digest[:12]}...)"}


_END = object()


def _in_turn(streams: Iterable[Iterable[Any]]) -> Iterator[Any]:
    """The items of ``streams``, one from each in turn (round robin) until every one is exhausted:
    ``["ab", "c", "de"]`` gives a, c, d, b, e."""
    iterators = [iter(stream) for stream in streams]
    while iterators:
        going = []
        for iterator in iterators:
            item = next(iterator, _END)
            if item is not _END:
                going.append(iterator)
                yield item
        iterators = going



Unit = tuple[str, int, dict[str, Any], int]
"""What a task scores one at a time: ``(category name, k, sample, v)``, view ``v`` of sequence ``k``
(for pairs, view 0 to view ``v``)."""


def _units(category: _Category, first_view: int) -> Iterator[Unit]:
    """``(category name, k, sample, v)`` for every view ``v >= first_view`` of each sequence ``k``, in
    order; a sequence is read when its first unit is asked for, and once."""
    for k in range(len(category.dataset)):
        sample = category.dataset[k]
        for v in range(first_view, len(sample["images"])):
            yield category.name, k, sample, v


def _sequences_needed(definition: TestSet, limit: int) -> int:
    """How many sequences of each category of ``definition`` the first ``limit`` units in turn
    (:func:`_in_turn`) come from: the most any category needs."""
    first = TASKS[definition.task].first_view
    return 1 + max(islice(_in_turn(_sequence_of_each_unit(c.count, c.config["n_views"] - first)
                                   for c in definition.categories), limit))


def _sequence_of_each_unit(count: int, per_sequence: int) -> Iterator[int]:
    return (k for k in range(count) for _ in range(per_sequence))


def _uint8(image: torch.Tensor) -> np.ndarray:
    """``(3, H, W)`` float in [0, 1] (8-bit levels) -> ``(H, W, 3)`` uint8."""
    return (image.permute(1, 2, 0) * 255).round().to(torch.uint8).numpy()


def _score_homographies(estimator: GuardedEstimator, units: Iterator[Unit]) -> dict[str, Any]:
    rows = []
    for category, k, sample, j in units:
        source, target = _uint8(sample["images"][0]), _uint8(sample["images"][j])
        scored = score_pair(estimator, source, target, sample["homographies"][0, j].double().numpy(),
                            f"{category} sequence {k}, view 0 -> {j}")
        rows.append({"category": category, **scored, **_difficulty(sample, 0, j, source.shape[:2])})
    return _homography_summary(rows)


def _patch_units(category: _Category, settings: dict[str, Any]) -> Iterator[tuple[str, int, dict[str, Any], Any]]:
    """``(category name, k, sample, pair)`` for every patch pair (:func:`draw_pairs`) of each sequence ``k``."""
    for k in range(len(category.dataset)):
        sample = category.dataset[k]
        for pair in draw_pairs(sample, k, **settings):
            yield category.name, k, sample, pair


def _score_patches(estimator: GuardedEstimator, units: Iterator[tuple[str, int, dict[str, Any], Any]]) -> dict[str, Any]:
    """The patch protocol's rows: corner errors at the patch's outer corners, difficulty of the view pair."""
    rows = []
    for category, k, sample, pair in units:
        cut = cut_pair(sample["images"], sample["homographies"][pair.source, pair.target].double().numpy(), pair)
        scored = score_pair(estimator, _uint8(cut["source"]), _uint8(cut["target"]), cut["H"],
                            f"{category} sequence {k}, views {pair.source} -> {pair.target}, box at {pair.origin}")
        rows.append({"category": category, **scored,
                     **_difficulty(sample, pair.source, pair.target, tuple(sample["images"].shape[-2:]))})
    if not rows:
        raise ValueError("protocol 'patches': no view pair shows enough painting for a patch pair")
    return _homography_summary(rows)


def _difficulty(sample: dict[str, Any], i: int, j: int, size: tuple[int, int]) -> dict[str, float]:
    """The pair's difficulty measures (see the module docstring); NaN where the data cannot say."""
    R = sample["R"].double().numpy() if "R" in sample else np.full((len(sample["images"]), 3, 3), np.nan)
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
    return {"pairs": len(rows), "mace": float(errors.mean()), "median_error": float(np.median(errors)),
            "success": {str(px): float((errors <= px).mean()) for px in SUCCESS_PX},
            "failures": sum(row["failed"] for row in rows)}


def _outcomes(rows: list[dict[str, Any]]) -> dict[str, int]:
    """``{"errors", "timeouts"}``: how many calls raised, and ran past the timeout."""
    return {"errors": sum(row["outcome"] == "raised" for row in rows),
            "timeouts": sum(row["outcome"] == "timed out" for row in rows)}


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
    return {**_pair_metrics(rows), **_outcomes(rows), "pair_errors": [row["error"] for row in rows],
            "median_seconds": float(np.median([row["seconds"] for row in rows])),
            "by_category": {name: _pair_metrics([row for row in rows if row["category"] == name]) for name in categories},
            "by_difficulty": by_difficulty}


def _lab(image: np.ndarray) -> np.ndarray:
    """``(H, W, 3)`` uint8 sRGB -> ``(H, W, 3)`` float64 CIELAB (L in [0, 100])."""
    tensor = torch.from_numpy(image).permute(2, 0, 1).float()[None] / 255
    return kornia.color.rgb_to_lab(tensor)[0].permute(1, 2, 0).double().numpy()


def _score_shadow_removal(estimator: GuardedEstimator, units: Iterator[Unit]) -> dict[str, Any]:
    """A view the estimator gives no answer for (it raised or timed out) is scored as left unchanged."""
    sums: dict[str | None, dict[str, list[float]]] = {}  # category (None: all of them) -> region -> [sum, pixels]
    rows = []
    for category, k, sample, v in units:
        view, target = _uint8(sample["images"][v]), _uint8(sample["shadow_free"][v])
        call = estimator(view, what=f"{category} sequence {k}, view {v}")
        rows.append({"outcome": call.outcome, "seconds": call.seconds})
        out = np.asarray(call.value) if call.outcome == "returned" else view
        if out.shape != view.shape or out.dtype != np.uint8:
            raise ValueError(f"estimator {estimator.name}: expected a {view.shape} uint8 image, got "
                             f"{out.shape} {out.dtype}")
        squared = ((_lab(out) - _lab(target)) ** 2).sum(-1)
        shadow = sample["shadow_masks"][v, 0].numpy() >= SHADOW_THRESHOLD
        for key in (category, None):
            totals = sums.setdefault(key, {"shadow": [0.0, 0], "non_shadow": [0.0, 0], "all": [0.0, 0]})
            for region, where in (("shadow", shadow), ("non_shadow", ~shadow), ("all", np.ones_like(shadow))):
                totals[region][0] += float(squared[where].sum())
                totals[region][1] += int(where.sum())

    def rmse(totals: dict[str, list[float]]) -> dict[str, float]:
        return {region: math.sqrt(s / n) if n else math.nan for region, (s, n) in totals.items()}

    return {"images": len(rows), "rmse": rmse(sums[None]), **_outcomes(rows),
            "median_seconds": float(np.median([row["seconds"] for row in rows])),
            "by_category": {name: {"rmse": rmse(totals)} for name, totals in sums.items() if name is not None}}


@dataclass(frozen=True)
class _Task:
    """How a task is scored: ``first_view``, the first view of a sequence scored (pairs: view 0 to
    each view from 1; shadow removal: every view), and ``score(estimator, units)``, the result's
    metrics from the units (:data:`Unit`) in the order they are to be scored."""

    first_view: int
    score: Callable[[GuardedEstimator, Iterator[Unit]], dict[str, Any]]


TASKS = {"homography": _Task(1, _score_homographies), "shadow-removal": _Task(0, _score_shadow_removal)}
"""A test set's ``task`` -> how it is scored."""


def format_table(result: dict[str, Any]) -> str:
    """The result of :func:`evaluate` as text: a summary line and markdown tables by category and
    difficulty; the row over all categories is labelled :data:`TOTAL`."""
    calls = (f"{result['errors']} raised, {result['timeouts']} ran past the {result['timeout']:g} s timeout"
             if result["timeout"] is not None else f"{result['errors']} raised, no timeout")
    if result["task"] == "shadow-removal":
        lines = [f"{result['set']}: {result['images']} views, estimator {result['estimator']}, "
                 f"median {result['median_seconds'] * 1e3:.1f} ms per view, {calls} (scored as the view unchanged); "
                 f"RMSE in CIELAB (shadow mask >= {SHADOW_THRESHOLD}: shadow region)", "",
                 "| category | shadow | non-shadow | all |", "|---|---|---|---|"]
        for name, metrics in [*result["by_category"].items(), (TOTAL, {"rmse": result["rmse"]})]:
            rmse = metrics["rmse"]
            lines.append(f"| {name} | {rmse['shadow']:.2f} | {rmse['non_shadow']:.2f} | {rmse['all']:.2f} |")
        return "\n".join(lines)
    protocol = result.get("protocol", {"name": "views"})
    pairs = ("pairs" if protocol["name"] == "views" else
             f"patch pairs ({protocol['patch']} px, corners moved up to {protocol['rho']:g} px, seed {protocol['seed']})")
    lines = [f"{result['set']}: {result['pairs']} {pairs}, estimator {result['estimator']}, "
             f"median {result['median_seconds'] * 1e3:.1f} ms per pair, {calls} (corner errors in pixels; a failure "
             f"scores as the identity)", "",
             "| category | pairs | MACE | median | <= 1 px | <= 3 px | <= 10 px | failures |",
             "|---|---|---|---|---|---|---|---|"]
    lines += [_row(name, metrics) for name, metrics in result["by_category"].items()]
    lines += [_row(TOTAL, result), "", "| difficulty | bin | pairs | MACE | median | <= 1 px | <= 3 px | <= 10 px | failures |",
              "|---|---|---|---|---|---|---|---|---|"]
    for measure, bins in result["by_difficulty"].items():
        lines += [_row(f"{measure} | {label}", metrics) for label, metrics in bins.items()]
    return "\n".join(lines)


def _row(label: str, metrics: dict[str, Any]) -> str:
    success = " | ".join(f"{100 * metrics['success'][str(px)]:.0f} %" for px in SUCCESS_PX)
    return (f"| {label} | {metrics['pairs']} | {metrics['mace']:.2f} | {metrics['median_error']:.2f} | {success} | "
            f"{metrics['failures']} |")
