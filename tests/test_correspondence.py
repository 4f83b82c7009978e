"""``sidar_torch.flow``'s inputs: what it refuses, and that a batch gives each item's answer. Its
geometry is proved by rendering (``tests/render/test_depth_flow.py``)."""

import re

import numpy as np
import pytest
import torch

from sidar_torch import flow


def plane_sample(views=3, size=(6, 8)):
    """A made-up sample of the keys flow reads: cameras over a plane at depth 2, shifted sideways."""
    K = torch.tensor([[10.0, 0, 3.5], [0, 10.0, 2.5], [0, 0, 1]]).expand(views, 3, 3)
    R = torch.eye(3).expand(views, 3, 3)
    t = torch.stack([torch.tensor([0.1 * k, 0.0, 0.0]) for k in range(views)])
    depth = torch.full((views, 1, *size), 2.0)
    depth[0, 0, 0, 0] = float("inf")
    return {"depth": depth, "K": K.clone(), "R": R.clone(), "t": t}


def test_a_batch_gives_each_items_flow():
    samples = [plane_sample(), plane_sample()]
    samples[1]["t"] = samples[1]["t"] * 2
    batch = {key: torch.stack([s[key] for s in samples]) for key in samples[0]}
    flows, valid = flow(batch, 0, 2)
    assert flows.shape == (2, 2, 6, 8) and valid.shape == (2, 1, 6, 8) and valid.dtype == torch.bool
    for k, sample in enumerate(samples):
        one = flow(sample, 0, 2)
        assert torch.equal(flows[k].nan_to_num(7.0), one[0].nan_to_num(7.0)) and torch.equal(valid[k], one[1])
    # t of view 2 is 0.2 (0.4) further along x: at depth 2 and focal length 10 the plane moves 1 (2) pixels right;
    # the pixel seeing nothing has no flow.
    assert torch.allclose(flows[0, 0, 1:, :], torch.tensor(1.0)) and torch.allclose(flows[1, 0, 1:, :], torch.tensor(2.0))
    assert torch.isnan(flows[0, :, 0, 0]).all() and torch.allclose(flows[:, 1, 1:, :], torch.tensor(0.0))
    assert not valid[0, 0, 0, 0] and valid[0, 0, 3, 4]


def test_wrong_inputs_name_what_is_wrong():
    sample = plane_sample()
    with pytest.raises(KeyError, match="depth_output"):
        flow({k: v for k, v in sample.items() if k != "depth"}, 0, 1)
    with pytest.raises(ValueError, match=r"j: expected a view index in \[0, 3\), got 3"):
        flow(sample, 0, 3)
    with pytest.raises(ValueError, match=r"i: expected a view index"):
        flow(sample, True, 1)
    with pytest.raises(ValueError, match="tolerance: expected a positive number"):
        flow(sample, 0, 1, tolerance=0)
    with pytest.raises(ValueError, match=r"sample\['K'\]: expected shape \(3, 3, 3\) to go with depth"):
        flow({**sample, "K": sample["K"][:2]}, 0, 1)
    with pytest.raises(ValueError, match=r"sample\['depth'\]: expected \(V, 1, H, W\)"):
        flow({**sample, "depth": sample["depth"][:, 0]}, 0, 1)
    with pytest.raises(ValueError, match=r"batch\['t'\]: expected a float tensor"):
        flow({**sample, "t": sample["t"].long()}, 0, 1)


def test_view_indices_and_tolerances_of_any_number_type_are_taken():
    # issue 48: flow(s, np.int64(1), 0) was refused, though config fields take NumPy numbers.
    sample = plane_sample()
    expected = flow(sample, 1, 0)
    for i, j in ((np.int64(1), np.int32(0)), (torch.tensor(1), np.uint8(0))):
        got = flow(sample, i, j, tolerance=np.float32(1e-3))
        assert torch.equal(got[0].nan_to_num(7.0), expected[0].nan_to_num(7.0)) and torch.equal(got[1], expected[1])
    for bad in (np.int64(3), np.float64(0.5), "1"):
        with pytest.raises(ValueError, match=rf"i: expected a view index in \[0, 3\), got {re.escape(repr(bad))}$"):
            flow(sample, bad, 0)
    with pytest.raises(ValueError, match="tolerance: expected a positive number, got nan"):
        flow(sample, 0, 1, tolerance=np.float64("nan"))


@pytest.mark.parametrize("view, name", [(1, "i"), (2, "j")])
@pytest.mark.parametrize("K, problem", [(torch.zeros(3, 3), r"singular \(rank 0\)"),
                                        (torch.tensor([[10.0, 0, 3.5], [20.0, 0, 7], [0, 0, 1]]), r"singular \(rank 2\)"),
                                        (torch.full((3, 3), float("nan")), "not finite")], ids=["zeros", "rank-2", "nan"])
def test_intrinsics_that_are_not_invertible_are_named_with_their_view(view, name, K, problem):
    # issue 48: a singular K of view i gave torch's LinAlgError, naming neither the view nor K.
    sample = plane_sample()
    sample["K"][view] = K
    i, j = (view, 0) if name == "i" else (0, view)
    with pytest.raises(ValueError, match=rf"^sample\['K'\]\[{view}\]: expected the invertible 3 x 3 intrinsics of view "
                                         rf"{name}={view}, got .*{problem}$"):
        flow(sample, i, j)
    batch = {key: torch.stack([plane_sample()[key], sample[key]]) for key in sample}
    with pytest.raises(ValueError, match=rf"^sample\['K'\]\[1, {view}\]: expected the invertible"):
        flow(batch, i, j)
    flow(sample, 0, 3 - view)  # the other views' intrinsics are fine


def test_depth_and_flow_are_refused_through_a_lens():
    from sidar_torch import load_config

    for switch in ("depth_output", "flow_output"):
        with pytest.raises(ValueError, match=f"'{switch}': expected false with lens_model 'division'"):
            load_config("lens", **{switch: True})
