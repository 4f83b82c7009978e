"""The shipped networks as estimators: weights that load and reproduce their recorded answers, and views of
any size mapped to and from the network's 128 x 128 pixels."""

import json
from importlib import resources

import numpy as np
import pytest
import torch

from benchmarks.transfer import recorded_offsets
from sidar_torch.evaluation.baselines import ESTIMATORS
from sidar_torch.deep_homography import estimators
from sidar_torch.deep_homography.network import CornerNet, ITERATIONS, SCALE
from sidar_torch.deep_homography.protocol import draw_pairs
from sidar_torch.deep_homography.warps import WarpTestSet

RECORD = json.loads((resources.files("sidar_torch.deep_homography") / "weights" / "scores.json").read_text())


@pytest.mark.parametrize("name", sorted(estimators.NETWORKS))
def test_the_shipped_weights_load_and_reproduce_their_recorded_answers(name):
    recorded = RECORD["networks"][name]
    assert estimators.weights_sha256(name) == recorded["sha256"]
    assert estimators.weights_sha256(name) != estimators.weights_sha256(
        next(other for other in estimators.NETWORKS if other != name))
    np.testing.assert_allclose(recorded_offsets(name), recorded["offsets"], atol=1e-3)
    assert len(recorded["offsets"]) == RECORD["recorded_pairs"] and name in ESTIMATORS


def test_a_view_of_any_size_is_mapped_to_the_networks_pixels_and_back(monkeypatch):
    """A network that moves every corner by (8, 4) px of its 128 px patch moves a 256 x 384 view's by
    (24, 8) px: the estimate is scaled back to the view's pixels."""
    network = CornerNet().eval()
    with torch.no_grad():
        network.update[-1].bias.copy_(torch.tensor([8.0, 4.0] * 4) / (SCALE * ITERATIONS))
    monkeypatch.setattr(estimators, "load_network", lambda name: network)
    view = np.random.default_rng(0).integers(0, 256, (256, 384, 3), dtype=np.uint8)
    H = estimators.network_estimator("sidar-net")(view, view)
    np.testing.assert_allclose(H / H[2, 2], [[1, 0, 24], [0, 1, 8], [0, 0, 1]], atol=1e-4)


def test_an_unknown_network_is_an_error_naming_the_choices():
    with pytest.raises(ValueError, match=r"network: expected one of \['sidar-net', 'warp-net'\], got 'x-net'"):
        estimators.weights_sha256("x-net")


@pytest.mark.parametrize("name", sorted(estimators.NETWORKS))
def test_the_shipped_networks_recorded_answers_beat_the_identity_on_their_pairs(name):
    """The recorded offsets are those of trained networks: on the first protocol pairs of ``warps-v1`` their
    mean corner error is under half the identity's (the perturbation's own size)."""
    data, truths = WarpTestSet(), []
    for k in range(len(data)):
        truths += [pair.offsets for pair in draw_pairs(data[k], k)]
        if len(truths) >= RECORD["recorded_pairs"]:
            break
    truth = np.array(truths[:RECORD["recorded_pairs"]])
    error = np.linalg.norm(np.array(RECORD["networks"][name]["offsets"]) - truth, axis=-1).mean()
    assert error < 0.5 * np.linalg.norm(truth, axis=-1).mean()
