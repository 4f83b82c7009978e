"""The training loop of the shipped networks: a few steps in seconds, resumable, both arms' pairs true."""

import kornia
import numpy as np
import pytest
import torch

from sidar_torch.deep_homography.training import SidarPairs, TrainSettings, WarpPairs, corner_loss, train
from sidar_torch.deep_homography.protocol import patch_homography


def _paintings(count: int = 3, size=(96, 128)) -> torch.Tensor:
    coarse = torch.rand(count, 3, size[0] // 8, size[1] // 8, generator=torch.Generator().manual_seed(0))
    smooth = torch.nn.functional.interpolate(coarse, size, mode="bicubic", align_corners=False).clamp(0, 1)
    return (smooth * 255).round().to(torch.uint8)


class _Stop(Exception):
    pass


def _stop(step, loss, seconds):
    raise _Stop


def test_a_run_stopped_after_a_step_resumes_to_the_weights_of_a_run_that_did_not_stop(tmp_path):
    pairs = WarpPairs(_paintings(), patch=32, rho=4)
    settings = TrainSettings(steps=3, batch=4, checkpoint_every=1)
    straight = train(pairs, settings)
    checkpoint = tmp_path / "run.ckpt"
    try:
        train(pairs, settings, checkpoint, _stop)  # the checkpoint of step 1 is written, then the run stops
    except _Stop:
        pass
    assert torch.load(checkpoint, weights_only=True)["step"] == 1
    reports = []
    resumed = train(pairs, settings, checkpoint, lambda *row: reports.append(row))
    assert [row[0] for row in reports] == [2, 3]  # the first step did not run again
    for name, value in straight.state_dict().items():
        torch.testing.assert_close(resumed.state_dict()[name], value, msg=name)


def test_the_loss_falls_on_a_tiny_set():
    pairs = WarpPairs(_paintings(1), patch=32, rho=4)
    losses = []
    train(pairs, TrainSettings(steps=20, batch=8, lr=3e-3, checkpoint_every=10), None,
          lambda step, loss, seconds: losses.append(loss))
    assert np.isfinite(losses).all() and losses[-1] < losses[0]


def _truth_lands(source, target, offsets, patch):
    """Mean difference between the target patch and the source patch moved by the offsets' homography."""
    Q = torch.from_numpy(patch_homography(offsets.double().numpy(), patch))[None]
    moved = kornia.geometry.transform.warp_perspective(source[None].double(), Q, (patch, patch), align_corners=True)
    return float((moved[0, :, 8:-8, 8:-8] - target[:, 8:-8, 8:-8].double()).abs().mean())


def test_both_arms_cut_pairs_whose_offsets_are_the_truth():
    paintings = _paintings(2)
    source, target, offsets = WarpPairs(paintings, patch=48, rho=8).batch(np.random.default_rng(0), 3)
    assert source.shape == target.shape == (3, 3, 48, 48) and offsets.shape == (3, 4, 2)
    # the warp arm's target is jittered: compare after standardising each patch
    standard = lambda x: (x - x.mean()) / x.std()  # noqa: E731
    for s, t, o in zip(source, target, offsets):
        assert _truth_lands(standard(s), standard(t), o, 48) < 0.35 * _truth_lands(standard(s), standard(t), 0 * o, 48)
    views = paintings[:, None].expand(2, 2, 3, 96, 128).contiguous()
    identity = torch.eye(3, dtype=torch.float64).expand(2, 2, 2, 3, 3).contiguous()
    sidar = SidarPairs(views, torch.zeros(2, 2, 1, 96, 128, dtype=torch.uint8), identity, patch=48, rho=8)
    source, target, offsets = sidar.batch(np.random.default_rng(1), 3)
    for s, t, o in zip(source, target, offsets):
        assert _truth_lands(s, t, o, 48) < 0.01 < _truth_lands(s, t, 0 * o, 48)


def test_corner_loss_weights_later_rounds_more():
    truth = torch.zeros(1, 4, 2)
    early = torch.stack([torch.ones(1, 4, 2), torch.zeros(1, 4, 2)])
    late = torch.stack([torch.zeros(1, 4, 2), torch.ones(1, 4, 2)])
    assert corner_loss(early, truth) == torch.tensor(0.85) and corner_loss(late, truth) == 1


def test_settings_refuse_a_budget_the_schedule_cannot_run():
    with pytest.raises(ValueError, match="steps"):
        TrainSettings(steps=2)
    with pytest.raises(ValueError, match="batch"):
        TrainSettings(batch=0)


def test_the_settings_choose_the_networks_input():
    pairs = WarpPairs(_paintings(1), patch=32, rho=4)
    assert train(pairs, TrainSettings(steps=3, batch=2, normalisation="standardised")).normalisation == "standardised"
    assert train(pairs, TrainSettings(steps=3, batch=2)).normalisation == "local_contrast"
    with pytest.raises(ValueError, match="normalisation: expected one of"):
        TrainSettings(normalisation="none")
