"""``sidar_torch.evaluate``: the metrics on hand-made exports (no rendering): the true homography
scores MACE 0 and success 1, one shifted by (3, 4) px MACE 5; failures, the result's keys, the
difficulty bins, the shadow-removal RMSE and the errors for wrong input."""

import json

import numpy as np
import pytest

from conftest import small_config
from sidar_torch import evaluate
from sidar_torch.evaluation import corner_error, format_table
from sidar_torch.io import WriteUnit
from sidar_torch.io.folders import FolderLayout
from sidar_torch.io.manifest import write_manifest
from sidar_torch.paintings import ProceduralPaintings
from sidar_torch.sample import SampleArrays

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
    masks[1, :, : w // 2] = 255
    free = rng.integers(20, 236, (n_views, h, w, 3), dtype=np.uint8)
    shadow_masks = np.zeros((n_views, h, w), np.uint8)
    shadow_masks[:, :, : w // 2] = 255
    images = free - (shadow_masks[..., None] > 0) * np.arange(n_views, dtype=np.uint8)[:, None, None, None]
    extra = {"shadow_masks": shadow_masks, "shadow_free": free} if shadows else {}
    return SampleArrays(images=images.astype(np.uint8), masks=masks, label=free[0], homographies=H,
                        homography_error=0.0, K=np.tile(np.eye(3), (n_views, 1, 1)),
                        R=np.tile(np.eye(3), (n_views, 1, 1)), t=np.zeros((n_views, 3)), index=index, **extra)


def export(out, count=2, shadows=False):
    """An export of ``count`` hand-made sequences (written through the folder layout, no rendering)."""
    out.mkdir()
    config = small_config(image_size=SIZE, shadow_mask_output=shadows, shadow_free_output=shadows,
                          geometry_dtype="float64").to_dict()
    write_manifest(out, 0, ProceduralPaintings(4), config, FolderLayout())
    for index in range(count):
        FolderLayout().write(out, WriteUnit(index, (index,)), lambda i: hand_made(i, shadows=shadows), lambda: None)
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
    assert "| **all** | 4 | 0.00 |" in format_table(true)


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
