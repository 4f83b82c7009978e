"""The SIDAR paper's layout (``sidar_torch.io.paper``): ours written in it reads back byte for byte,
its ``H_i_j.mat`` are the paper's text in the paper's pixels, and folders of the paper's own
sequences (no ``export.json``) read with their homographies converted to Kornia pixels.

The six sequences of the paper's generator are checked when ``SIDAR_PAPER_SEQUENCES`` names a
folder of them (skipped otherwise: users do not have them)."""

import itertools
import os
from pathlib import Path

import numpy as np
import pytest
import torch
from PIL import Image

from conftest import TINY, assert_same_sample
from sidar_torch import ExportedDataset, SidarDataset, export_dataset, geometry, load_config
from sidar_torch.io.paper import PaperLayout, kornia_from_paper, paper_from_kornia

SIZE = (6, 8)  # (H, W) of the hand-made paper sequences


def corners_after(H, corners):
    """``corners`` ``(4, 2)`` mapped by ``H`` ``(3, 3)``."""
    mapped = np.c_[corners, np.ones(len(corners))] @ np.asarray(H, np.float64).T
    return mapped[:, :2] / mapped[:, 2:]


def test_the_paper_pixels_put_the_image_edges_at_0_and_w_minus_1():
    h, w = SIZE
    shift = np.array([[1.0, 0, 3], [0, 1, 4], [0, 0, 1]])  # (3, 4) px in Kornia pixels
    paper = paper_from_kornia(shift, SIZE)
    np.testing.assert_allclose(np.linalg.det(paper), 1.0)
    np.testing.assert_allclose(corners_after(paper, np.array([[0.0, 0.0]])), [[3 * (w - 1) / w, 4 * (h - 1) / h]])
    np.testing.assert_allclose(kornia_from_paper(paper, SIZE), shift, atol=1e-12)


@pytest.mark.gl
def test_ours_in_the_paper_layout_reads_back_byte_for_byte_with_the_papers_homography_texts(tmp_path):
    dataset = SidarDataset(config=load_config("misaligned", **{**TINY, "n_views": 3}), seed=5)
    export_dataset(dataset, tmp_path, 2, layout="paper", progress=False)
    read = ExportedDataset(tmp_path)
    assert read.layout == "paper" and read.indices == [0, 1]
    for k, index in enumerate(read.indices):
        assert_same_sample(read[k], dataset.sample(index))
        folder = tmp_path / f"{index:06d}"
        arrays = dataset.sample_arrays(index)
        assert {p.name: p.read_bytes() for p in folder.iterdir()} == PaperLayout().files(arrays)
        for i, j in itertools.permutations(range(3), 2):
            assert (folder / f"H_{i}_{j}.mat").exists() == (i < j)
        text = (folder / "H_0_2.mat").read_text().splitlines()
        assert len(text) == 3 and all(len(line.split()) == 3 for line in text)
        H = np.loadtxt(folder / "H_0_2.mat")
        np.testing.assert_allclose(np.linalg.det(H), 1.0, rtol=1e-12)
        np.testing.assert_allclose(H, paper_from_kornia(arrays.homographies[0, 2], TINY["image_size"]), rtol=1e-15)


def paper_sequence(folder, rng, H_paper):
    """A 2-view sequence as the paper's generator writes it: RGBA PNGs, a mask with a grey edge,
    ``H_0_1.mat`` as ``np.savetxt`` text."""
    folder.mkdir()
    h, w = SIZE
    for name in ("gt.png", "0.png", "1.png"):
        Image.fromarray(rng.integers(0, 256, (h, w, 4), dtype=np.uint8)).save(folder / name)
    for v in range(2):
        mask = np.zeros((h, w, 4), np.uint8)
        mask[:, :2], mask[:, 2], mask[..., 3] = 255, 127 + v, 255  # white left, a grey edge (127, then 128)
        Image.fromarray(mask).save(folder / f"{v}-m.png")
    np.savetxt(folder / "H_0_1.mat", H_paper)


def test_a_folder_of_the_papers_sequences_reads_with_its_homographies_in_kornia_pixels(tmp_path):
    rng = np.random.default_rng(0)
    H_paper = np.array([[1.1, 0.05, 2.0], [0.02, 0.95, -1.0], [0.001, 0.002, 1.0]])
    H_paper /= np.cbrt(np.linalg.det(H_paper))
    paper_sequence(tmp_path / "seq02", rng, H_paper)
    paper_sequence(tmp_path / "seq01", rng, H_paper * 2)  # any scale: read back det = 1
    (tmp_path / "notes").mkdir()  # not a sequence: no gt.png

    read = ExportedDataset(tmp_path)
    assert read.layout == "paper" and read.seed is None and read.indices == [0, 1]
    assert read.config == {"image_size": list(SIZE), "n_views": 2}
    sample = read[1]  # seq02, in name order
    with Image.open(tmp_path / "seq02" / "1.png") as view:
        expected = torch.from_numpy(np.asarray(view)[..., :3].copy()).permute(2, 0, 1).float() / 255
    assert torch.equal(sample["images"][1], expected)
    assert sample["masks"][:, 0, :, :3].tolist() == [[[1, 1, 0]] * 6, [[1, 1, 1]] * 6]
    H = sample["homographies"].double()
    h, w = SIZE
    paper_points = np.array([[0.0, 0.0], [w - 1, 0], [2.0, 3.0]])  # the paper's pixels: image edges at 0 and W-1
    scale = np.array([w / (w - 1), h / (h - 1)])  # paper -> Kornia pixels: x_k = x_p W / (W - 1) - 1/2
    np.testing.assert_allclose(corners_after(H[0, 1].numpy(), paper_points * scale - 0.5),
                               corners_after(H_paper, paper_points) * scale - 0.5, atol=1e-5)
    np.testing.assert_allclose(np.linalg.det(H[0, 1].numpy()), 1.0, rtol=1e-6)
    np.testing.assert_allclose((H[1, 0] @ H[0, 1]).numpy(), np.eye(3), atol=1e-6)
    assert torch.isnan(sample["K"]).all() and np.isnan(sample["homography_error"])


def test_a_folder_of_neither_kind_and_a_bad_homography_text_are_errors_naming_the_file(tmp_path):
    with pytest.raises(ValueError, match=r"no export.json\) nor a folder of the SIDAR paper's sequences"):
        ExportedDataset(tmp_path)
    rng = np.random.default_rng(0)
    paper_sequence(tmp_path / "seq01", rng, np.eye(3))
    (tmp_path / "seq01" / "H_0_1.mat").write_text("1 0 0\n0 1\n")
    with pytest.raises(ValueError, match=r"H_0_1.mat'.*expected 3 lines of 3 numbers"):
        ExportedDataset(tmp_path)[0]


@pytest.mark.skipif(not os.environ.get("SIDAR_PAPER_SEQUENCES"),
                    reason="set SIDAR_PAPER_SEQUENCES to a folder of sequences made by the paper's generator")
def test_the_papers_sequences_read_with_view_0s_corners_landing_on_the_painting_in_every_view():
    read = ExportedDataset(Path(os.environ["SIDAR_PAPER_SEQUENCES"]))
    assert len(read) >= 1
    on_plane = []
    for sample in read:
        masks, H = sample["masks"][:, 0].numpy(), sample["homographies"].double().numpy()
        h, w = masks.shape[1:]
        corners = geometry.corner_pixels((h, w))
        for j in range(1, len(masks)):
            quad = corners_after(H[0, j], corners)
            inside = quad.mean(0) + 0.97 * (quad - quad.mean(0))  # 3 % inside the painting's corners
            seen = [(round(x), round(y)) for x, y in inside if 0 <= round(x) < w and 0 <= round(y) < h]
            on_plane += [masks[j, y, x] == 0 for x, y in seen]  # an occluder may cover one
            # and the plane region of mask j lies in the mapped quadrilateral (1 px of slack for its grey edges)
            rows, columns = np.nonzero(masks[j] == 0)
            back = corners_after(H[j, 0], np.c_[columns, rows])
            outside = (back < -1.5).any(1) | (back[:, 0] > w + 0.5) | (back[:, 1] > h + 0.5)
            assert outside.mean() < 0.01, j
    assert np.mean(on_plane) > 0.9, on_plane
