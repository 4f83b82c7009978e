"""``sidar_torch.evaluate``: the metrics on hand-made exports (no rendering): the true homography
scores MACE 0 and success 1, one shifted by (3, 4) px MACE 5; failures, the result's keys, the
difficulty bins, the shadow-removal RMSE and the errors for wrong input; ``limit`` in turn across
categories, estimators that raise, hang or answer nonsense (issue 48)."""

import json
import math
import re
import threading
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import torch

from conftest import small_config
from sidar_torch import evaluate
from sidar_torch.evaluation import scoring as evaluation
from sidar_torch.evaluation.scoring import corner_error, format_table
from sidar_torch.io import WriteUnit
from sidar_torch.io.folders import FolderLayout
from sidar_torch.io.manifest import write_manifest
from sidar_torch.paintings import ProceduralPaintings
from sidar_torch.sample import SampleArrays
from sidar_torch.evaluation.testsets import load_testset

ROOT = Path(__file__).resolve().parent.parent

SIZE = (12, 16)  # (H, W)
H_TRUE = np.array([[1.05, 0.02, 1.5], [-0.01, 0.98, -2.0], [1e-4, 2e-4, 1.0]])
"""View 0 to view j of every hand-made sequence."""
SHIFT = np.array([[1.0, 0, 3], [0, 1, 4], [0, 0, 1]])


def hand_made(index, n_views=3, shadows=False):
    """A sequence whose views 1.. are view 0 under :data:`H_TRUE` (as homographies say; pixels random),
    half of view 1 occluded; with ``shadows``, view ``v`` darker than its shadow-free self by ``v``
    levels where the shadow mask is 255 (its left half)."""
    rng = np.random.default_rng(index)
    h, w = SIZE
    H = np.stack([np.stack([np.eye(3) if i == j else (H_TRUE if i == 0 else np.linalg.inv(H_TRUE) if j == 0 else
                                                       np.eye(3)) for j in range(n_views)]) for i in range(n_views)])
    masks = np.zeros((n_views, h, w), np.uint8)
    masks[1:2, :, : w // 2] = 255
    free = rng.integers(20, 236, (n_views, h, w, 3), dtype=np.uint8)
    shadow_masks = np.zeros((n_views, h, w), np.uint8)
    shadow_masks[:, :, : w // 2] = 255
    images = free - (shadow_masks[..., None] > 0) * np.arange(n_views, dtype=np.uint8)[:, None, None, None]
    extra = {"shadow_masks": shadow_masks, "shadow_free": free} if shadows else {}
    return SampleArrays(images=images.astype(np.uint8), masks=masks, label=free[0], homographies=H,
                        homography_error=0.0, K=np.tile(np.eye(3), (n_views, 1, 1)),
                        R=np.tile(np.eye(3), (n_views, 1, 1)), t=np.zeros((n_views, 3)), index=index, **extra)


def export(out, count=2, shadows=False, n_views=3):
    """An export of ``count`` hand-made sequences (written through the folder layout, no rendering)."""
    out.mkdir()
    config = small_config(image_size=SIZE, shadow_mask_output=shadows, shadow_free_output=shadows,
                          geometry_dtype="float64", n_views=n_views).to_dict()
    write_manifest(out, 0, ProceduralPaintings(4), config, FolderLayout())
    for index in range(count):
        FolderLayout().write(out, WriteUnit(index, (index,)), lambda i: hand_made(i, n_views, shadows), lambda: None)
    return out


def test_the_true_homography_scores_0_and_one_shifted_by_3_4_px_scores_5():
    assert corner_error(H_TRUE, H_TRUE, SIZE) == pytest.approx(0, abs=1e-12)
    assert corner_error(SHIFT @ H_TRUE, H_TRUE, SIZE) == pytest.approx(5)
    assert corner_error(None, H_TRUE, SIZE) == corner_error(np.eye(3), H_TRUE, SIZE) > 0


def test_evaluate_scores_estimators_on_a_folder_per_category_and_difficulty(tmp_path):
    folder = export(tmp_path / "set")
    true = evaluate(lambda a, b: H_TRUE, testset=folder)
    assert true["pairs"] == 4 and true["mace"] == pytest.approx(0, abs=1e-9) and true["failures"] == 0
    assert true["success"] == {"1": 1.0, "3": 1.0, "10": 1.0}
    assert set(true) >= {"set", "estimator", "pairs", "mace", "success", "failures", "by_category", "by_difficulty"}
    assert true["by_category"] == {"set": {key: true[key] for key in ("pairs", "mace", "median_error", "success",
                                                                       "failures")}}
    json.dumps(true)  # what --json writes

    shifted = evaluate(lambda a, b: SHIFT @ H_TRUE, testset=folder)
    assert shifted["mace"] == pytest.approx(5) and shifted["success"] == {"1": 0.0, "3": 0.0, "10": 1.0}

    failing = evaluate(lambda a, b: None, testset=folder, limit=3)
    assert failing["pairs"] == 3 and failing["failures"] == 3
    assert failing["mace"] == pytest.approx(corner_error(np.eye(3), H_TRUE, SIZE))
    assert evaluate("identity", testset=folder)["mace"] == pytest.approx(failing["mace"])

    difficulty = true["by_difficulty"]
    assert difficulty["tilt_deg"] == {"[0, 20)": difficulty["tilt_deg"]["[0, 20)"]}  # identical cameras: 0 degrees
    assert sum(b["pairs"] for b in difficulty["occluded"].values()) == 4
    assert {b["pairs"] for label, b in difficulty["occluded"].items() if label != "[0, 0.01)"} == {2}  # view 1: half
    assert "unknown" in difficulty["shadowed"]  # no shadow masks in this set
    assert "| **total** | 4 | 0.00 |" in format_table(true)


def test_evaluate_reads_an_export_of_a_testset_as_its_categories(tmp_path):
    export(tmp_path / "clean", count=2)
    export(tmp_path / "shadows", count=2)
    result = evaluate(lambda a, b: H_TRUE, testset=tmp_path, limit=5)  # 2 pairs per sequence
    assert list(result["by_category"]) == ["clean", "shadows"]  # in turn: clean 0, shadows 0, clean 1 (one pair)
    assert [result["by_category"][c]["pairs"] for c in ("clean", "shadows")] == [3, 2]


def test_the_shadow_removal_rmse_is_zero_outside_the_shadow_and_grows_with_it(tmp_path):
    folder = export(tmp_path / "set", count=1, shadows=True)
    result = evaluate("identity", testset=folder)
    assert result["task"] == "shadow-removal" and result["images"] == 3
    rmse = result["rmse"]
    assert rmse["non_shadow"] == 0 and rmse["shadow"] > 0 and 0 < rmse["all"] < rmse["shadow"]
    assert "| set |" in format_table(result)
    with pytest.raises(ValueError, match=r"expected a \(12, 16, 3\) uint8 image, got \(12, 16\) uint8"):
        evaluate(lambda view: view[..., 0], testset=folder)


def test_wrong_input_is_an_error_naming_it(tmp_path):
    folder = export(tmp_path / "set", count=1)
    with pytest.raises(ValueError, match=r"estimator .*expected a \(3, 3\) homography or None, got shape \(2, 2\)"):
        evaluate(lambda a, b: np.eye(2), testset=folder)
    with pytest.raises(ValueError, match=r"limit: expected an integer >= 1 or None, got 0"):
        evaluate("identity", testset=folder, limit=0)
    with pytest.raises(ValueError, match=r"testset: expected one of \['homography-v1', .* or a folder, got 'nope'"):
        evaluate("identity", testset="nope")
    with pytest.raises(ValueError, match=r"estimator: expected one of \[.*'sift'.*\] or MODULE:FUNCTION, got 'nope'"):
        evaluate("nope", testset=folder)


def pairs_by_category(result):
    return {name: metrics["pairs"] for name, metrics in result["by_category"].items()}


def test_limit_takes_pairs_one_from_each_category_in_turn(tmp_path):
    """Issue 48: ``--limit 8`` took whole sequences in turn, 3 + 3 + 2 pairs from the first three
    categories and none from the last two."""
    for name in ("a", "b", "c"):
        export(tmp_path / name, count=2)  # 2 pairs per sequence
    assert pairs_by_category(evaluate(lambda a, b: H_TRUE, testset=tmp_path, limit=4)) == {"a": 2, "b": 1, "c": 1}
    assert pairs_by_category(evaluate(lambda a, b: H_TRUE, testset=tmp_path)) == {"a": 4, "b": 4, "c": 4}


def test_limit_10_on_homography_v1_scores_all_five_categories_and_renders_one_sequence_of_each(monkeypatch):
    """The set's sequences are stood in for by hand-made ones of as many views (4: 3 pairs each)."""
    definition = load_testset("homography-v1")
    asked = []

    def render(testset, folder, sequences, progress):
        asked.append(sequences)
        for category in testset.categories:
            export(folder / category.name, count=sequences, n_views=category.config["n_views"])
        return SimpleNamespace(matches=None, checked=0, differing=[], summary=lambda: "not checked")

    monkeypatch.setattr(evaluation, "export_testset", render)
    result = evaluate(lambda a, b: H_TRUE, testset="homography-v1", limit=10)
    names = [category.name for category in definition.categories]
    assert len(names) == 5 and pairs_by_category(result) == dict.fromkeys(names, 2) and asked == [1]
    per_sequence = {category.config["n_views"] - 1 for category in definition.categories}
    assert per_sequence == {3}  # so 15 pairs in turn come from one sequence of each, the 16th from a second
    assert evaluation._sequences_needed(definition, 15) == 1 and evaluation._sequences_needed(definition, 16) == 2


def test_the_total_row_has_a_name_no_category_has(tmp_path):
    """Issue 48: the bold total row was named ``**all**``, like homography-v1's category ``all``."""
    export(tmp_path / "all")
    export(tmp_path / "clean")
    lines = format_table(evaluate(lambda a, b: H_TRUE, testset=tmp_path)).splitlines()
    table = lines[lines.index("| category | pairs | MACE | median | <= 1 px | <= 3 px | <= 10 px | failures |") + 2:]
    rows = table[:table.index("")]
    assert [row.split(" | ")[0] for row in rows] == ["| all", "| clean", f"| {evaluation.TOTAL}"]
    assert rows[-1].startswith(f"| {evaluation.TOTAL} | 8 |") and "all" not in evaluation.TOTAL


def test_the_failure_rule_is_written_beside_mace_in_the_docs():
    text = (ROOT / "docs" / "benchmarks.md").read_text()
    metrics = text[text.index("## Metrics"):text.index("## Baselines")]
    assert "|det(H / max|H|)| < " + f"{evaluation.SINGULAR_DET:g}" in metrics
    assert f"|w| < {evaluation.HORIZON_W:g} |(x, y, w)|" in metrics
    assert "round robin" in text and f"--timeout SECONDS`\n(default {evaluation.DEFAULT_TIMEOUT:g} s" in text


IDENTITY_ERROR = corner_error(np.eye(3), H_TRUE, SIZE)


@pytest.mark.parametrize("answer", [
    np.zeros((3, 3)),
    [[1, 0, 0], [0, 1, 0], [2, 0, 1]],  # the corner (-0.5, -0.5) at infinity
    [[1, 0, 0], [0, 1, 0], [-0.1, 0, 1]],  # the right corners behind the camera
    [[1, 0, 0], [0, 1, 0], [2, 0, 1 + 1e-14]],  # a corner 1e14 px away
    [[1, 2, 3], [2, 4, 6], [0, 0, 1]],  # singular
    [[1, 0, math.nan], [0, 1, 0], [0, 0, 1]],
], ids=["zeros", "horizon", "behind", "near-horizon", "singular", "nan"])
def test_an_answer_with_no_finite_corner_error_is_a_failure(tmp_path, answer):
    """Issue 48: zeros scored MACE nan with 0 failures, a corner sent to infinity MACE inf."""
    result = evaluate(lambda a, b: answer, testset=export(tmp_path / "set", count=1))
    assert result["failures"] == result["pairs"] == 2 and result["mace"] == pytest.approx(IDENTITY_ERROR)
    assert all(math.isfinite(m["mace"]) for bins in result["by_difficulty"].values() for m in bins.values())


def test_a_huge_scale_is_the_same_homography():
    """``1e307 * H`` maps every point as ``H``: scored so, without overflow (``1e308 * I`` gave MACE inf)."""
    assert corner_error(1e307 * H_TRUE, H_TRUE, SIZE) == pytest.approx(0, abs=1e-9)
    assert corner_error(-1e-300 * SHIFT @ H_TRUE, H_TRUE, SIZE) == pytest.approx(5)
    assert evaluation._checked(1e308 * np.eye(3), "e", SIZE) is not None


@pytest.mark.parametrize("answer, shown", [("abc", "str 'abc'"), ({"H": 1}, "dict {'H': 1}"),
                                           ([[1, 2], [3]], r"list \[\[1, 2\], \[3\]\]"),
                                           (np.eye(3, dtype=complex), r"ndarray array\(")])
def test_an_answer_that_is_no_matrix_is_an_error_naming_the_estimator(tmp_path, answer, shown):
    def wrong(a, b):
        return answer

    with pytest.raises(ValueError, match=rf"estimator {__name__}:.*wrong: expected a \(3, 3\) homography or None, "
                                         rf"got {shown}"):
        evaluate(wrong, testset=export(tmp_path / "set", count=1))


def test_an_estimator_that_raises_scores_a_failure_keeps_its_traceback_and_the_run_goes_on(tmp_path, capsys):
    """Issue 48: one exception stopped the whole run."""
    calls = []

    def flaky(source, target):
        calls.append(source)
        if len(calls) in (1, 3):
            raise RuntimeError("no estimate here")
        return H_TRUE

    result = evaluate(flaky, testset=export(tmp_path / "set"))
    assert result["pairs"] == 4 and result["errors"] == 2 and result["failures"] == 2 and result["timeouts"] == 0
    assert result["mace"] == pytest.approx(IDENTITY_ERROR / 2)
    err = capsys.readouterr().err
    assert err.count("raised on set sequence ") == 2 and err.count("RuntimeError: no estimate here") == 3
    assert err.count("Traceback (most recent call last)") == 1 and "in flaky" in err  # the traceback, once
    assert "2 raised" in format_table(result)


def test_a_missing_package_or_file_in_the_estimator_stops_the_run(tmp_path):
    def needs_opencv(source, target):
        raise ImportError("needs OpenCV")

    with pytest.raises(ImportError, match="needs OpenCV"):
        evaluate(needs_opencv, testset=export(tmp_path / "set", count=1))


def test_a_call_past_the_timeout_is_stopped_and_scored_as_a_failure_and_the_run_goes_on(tmp_path, capsys):
    """Issue 48: an estimator that sleeps hung the run. A Python loop is stopped inside the call; a wait
    in C is left behind (released at the end of the test). Each holds out 20 s at most, so that without
    a timeout the test ends, and fails."""
    release, stopped, calls = threading.Event(), threading.Event(), []

    def hangs_twice(source, target):
        calls.append(source)
        if len(calls) == 1:  # a Python loop
            try:
                deadline = time.monotonic() + 20
                while time.monotonic() < deadline:
                    pass
            finally:
                stopped.set()
        if len(calls) == 2:  # a wait in C
            release.wait(20)
        return H_TRUE

    try:
        result = evaluate(hangs_twice, testset=export(tmp_path / "set"), timeout=0.5)
    finally:
        release.set()
    assert result["timeouts"] == 2 and result["failures"] == 2 and result["pairs"] == 4 and result["errors"] == 0
    assert result["mace"] == pytest.approx(IDENTITY_ERROR / 2) and result["timeout"] == 0.5
    assert stopped.wait(5)  # the loop was stopped, not left running
    assert capsys.readouterr().err.count("after 0.5 s: stopped, scored as a failure") == 2


def test_without_a_timeout_the_estimator_runs_in_the_calling_thread(tmp_path):
    def where(source, target):
        return H_TRUE if threading.current_thread() is threading.main_thread() else None

    folder = export(tmp_path / "set", count=1)
    assert evaluate(where, testset=folder, timeout=None)["failures"] == 0
    assert evaluate(where, testset=folder)["failures"] == 2


@pytest.mark.parametrize("timeout, message", [
    (0, "expected seconds > 0"), (-1, "expected seconds > 0"), (1e300, "expected seconds > 0 and at most"),
    (math.nan, "expected a finite number"), (math.inf, "expected a finite number"), (True, "expected a number"),
    ("5", "expected a number")])
def test_a_wrong_timeout_is_an_error_naming_it(tmp_path, timeout, message):
    with pytest.raises(ValueError, match=rf"^timeout: {message}"):
        evaluate("identity", testset=export(tmp_path / "set", count=1), timeout=timeout)


def test_an_export_with_nothing_to_score_is_an_error_naming_it(tmp_path):
    """Issue 48: an export of no sequences crashed in format_table (TypeError on median_seconds None);
    one of single views has no pair either."""
    with pytest.raises(ValueError, match=re.escape(repr(str(tmp_path / "none")))):
        evaluate("identity", testset=export(tmp_path / "none", count=0))
    folder = export(tmp_path / "single", count=1, n_views=1)
    with pytest.raises(ValueError, match=rf"testset {str(folder)!r}: nothing to score, no sequence of 2 views or more"):
        evaluate("identity", testset=folder)


def test_a_shadow_removal_estimator_that_raises_scores_the_view_unchanged(tmp_path, capsys):
    folder = export(tmp_path / "set", count=1, shadows=True)

    def broken(view):
        raise RuntimeError("no shadow-free view")

    result = evaluate(broken, testset=folder)
    assert result["errors"] == result["images"] == 3 and result["rmse"] == evaluate("identity", testset=folder)["rmse"]
    assert f"| {evaluation.TOTAL} |" in format_table(result)


def test_the_truth_is_read_in_float64_whatever_the_export_recorded(tmp_path):
    """The paper's folders record no dtype and read as float32 by default, 15.7 px off near the horizon:
    evaluate reads every folder's geometry in float64."""
    out = tmp_path / "export"
    out.mkdir()
    config = small_config(image_size=SIZE, geometry_dtype="float32", n_views=3).to_dict()
    write_manifest(out, 0, ProceduralPaintings(4), config, FolderLayout())
    FolderLayout().write(out, WriteUnit(0, (0,)), lambda i: hand_made(i), lambda: None)
    seen = []
    evaluate(lambda source, target: seen.append(1) or np.eye(3), str(out), timeout=None)
    _, _, categories, _, _ = evaluation._open(str(out), None, None, False, None)
    assert categories[0].dataset[0]["homographies"].dtype == torch.float64 and seen
