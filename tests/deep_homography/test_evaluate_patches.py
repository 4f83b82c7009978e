"""``evaluate(..., protocol="patches")``: the truth scores 0, a known shift its size, the same seed the same pairs."""

import numpy as np
import pytest

from sidar_torch import evaluate
from sidar_torch.cli import main
from sidar_torch.deep_homography.protocol import draw_pairs, patch_homography
from sidar_torch.deep_homography.warps import WARPS_V1_SHA256, WarpTestSet

SETTINGS = {"patch": 64, "rho": 16}
SHIFT = np.array([[1.0, 0, 3], [0, 1, 4], [0, 0, 1]])


def truths(sequences: int, seed: int = 0) -> list[np.ndarray]:
    """The truths of warps-v1's patch pairs, in the order evaluate scores them (one category: in order)."""
    data = WarpTestSet()
    return [patch_homography(pair.offsets, SETTINGS["patch"])
            for k in range(sequences) for pair in draw_pairs(data[k], k, seed=seed, **SETTINGS)]


def test_the_true_perturbation_scores_0():
    expected = iter(truths(3))
    result = evaluate(lambda source, target: next(expected), "warps-v1", limit=6, protocol="patches", timeout=None,
                      **SETTINGS)
    assert result["pairs"] == 6 and result["mace"] == pytest.approx(0, abs=1e-9) and result["failures"] == 0
    assert result["protocol"] == {"name": "patches", "seed": 0, "min_visible": 0.5, **SETTINGS}


def test_a_known_shift_scores_its_size():
    """With no perturbation (rho 0) the truth is the identity: a shift by (3, 4) px scores 5 px at every corner."""
    result = evaluate(lambda source, target: SHIFT, "warps-v1", limit=4, protocol="patches", timeout=None,
                      patch=64, rho=0)
    assert result["mace"] == pytest.approx(5) and result["median_error"] == pytest.approx(5)


def test_the_estimator_sees_the_two_patches():
    seen = []

    def estimator(source, target):
        seen.append((source.shape, source.dtype, target.shape))
        return np.eye(3)

    evaluate(estimator, "warps-v1", limit=2, protocol="patches", timeout=None, **SETTINGS)
    assert seen == [((64, 64, 3), np.uint8, (64, 64, 3))] * 2


def test_the_same_seed_gives_the_same_pairs_and_another_seed_others():
    identity = lambda source, target: np.eye(3)  # noqa: E731
    runs = [evaluate(identity, "warps-v1", limit=4, protocol="patches", seed=seed, timeout=None, **SETTINGS)["mace"]
            for seed in (0, 0, 1)]
    assert runs[0] == runs[1] != runs[2]
    assert truths(2, 0)[0].tolist() != truths(2, 1)[0].tolist()


def test_a_wrong_protocol_or_task_is_an_error_naming_it():
    with pytest.raises(ValueError, match="protocol: expected one of"):
        evaluate("identity", "warps-v1", limit=1, protocol="patch")


@pytest.mark.slow
def test_warps_v1_is_the_set_it_was_recorded_as():
    assert WarpTestSet().digest() == WARPS_V1_SHA256


def test_the_cli_scores_patches_of_a_generated_set(capsys):
    main(["evaluate", "--testset", "warps-v1", "--estimator", "identity", "--protocol", "patches", "--limit", "2",
          "--patch", "64", "--rho", "16"])
    out = capsys.readouterr().out
    assert "warps-v1: 2 patch pairs (64 px, corners moved up to 16 px, seed 0)" in out
