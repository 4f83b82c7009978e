"""Views through a lens (``lens_model``; ``sidar_torch.sample.lens_views``, ``sidar_torch.choices.lenses``), checked by
rendering and by tools the project did not write: OpenCV's Brown-Conrady model (``cv2.undistort``,
``cv2.undistortPoints``) and homlib's radial-distortion homography solvers (division model)."""

import re
from pathlib import Path

import numpy as np
import pytest
import torch
from PIL import Image, ImageFilter

from conftest import assert_same_sample, small_config
from sidar_torch import ExportedDataset, SidarDataset, export_dataset, load_config, undistort
from sidar_torch.config.allowed import LENS_MODELS as LENS_CHOICES
from sidar_torch.choices import lenses
from sidar_torch.choices.lenses import (LEAST_SLOPE, LENS_MODELS, distorted_points, lens_folds, scaled_lens,
                                         undistorted_points)
from sidar_torch.geometry import plane_corners, project
from sidar_torch.sample import render_arrays, stack_samples
from sidar_torch.sample.lens_views import distortion_maps
from sidar_torch.scene import sample_sequence
from sidar_torch.timing import collect_timings

ZERO_LENS = dict(lens_k1=(0, 0), lens_k2=(0, 0), lens_k3=(0, 0), lens_p1=(0, 0), lens_p2=(0, 0))
EVERYTHING = dict(opacity_output=True, shadow_mask_output=True, shadow_free_output=True, background="view",
                  exposure_jitter=True, sensor_noise=True, distortion_map_output=True, n_occluders=(2, 3))


def psnr(a, b):
    return 10 * np.log10(255.0**2 / np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2))


def test_the_config_choices_are_the_model_table_and_a_folding_lens_is_refused_by_name():
    assert LENS_CHOICES == ("none", *LENS_MODELS)
    with pytest.raises(ValueError, match="config field 'lens_model': expected one of"):
        load_config("misaligned", lens_model="fisheye")
    with pytest.raises(ValueError, match="config fields 'lens_k1', 'lens_k2', 'lens_p1', 'lens_p2', 'lens_k3': "
                                         "expected ranges of lens_model 'brown_conrady'"):
        load_config("misaligned", lens_model="brown_conrady", lens_k1=(-0.3, 0.0))
    with pytest.raises(ValueError, match="config field 'lens_lambda'"):
        load_config("misaligned", lens_model="division", lens_lambda=(-0.9, 0.0))
    for switch in ("depth_output", "flow_output"):  # pinhole only: the lens step would resample them as images
        with pytest.raises(ValueError, match=f"config field '{switch}': expected false with lens_model 'division'"):
            load_config("misaligned", lens_model="division", **{switch: True})
        assert getattr(load_config("misaligned", **{switch: True}), switch)


def test_the_lens_draws_change_no_other_draw():
    config = load_config("misaligned", n_views=4, lens_model="division")
    for index in range(3):
        with_lens, without = np.random.default_rng([7, index]), np.random.default_rng([7, index])
        a, b = sample_sequence(config, with_lens), sample_sequence(config.replace(lens_model="none"), without)
        assert a.views == b.views and b.lenses is None and a.lenses.shape == (4, 5)
        assert with_lens.random(8).tolist() == without.random(8).tolist()  # what is drawn next: the view effects


@pytest.mark.gl
@pytest.mark.parametrize("model", ["brown_conrady", "division"])
def test_a_lens_of_zeros_renders_the_pinhole_sample_byte_for_byte(model):
    """The lens path (draws, canvas, resampling) with every coefficient 0 gives every key of the sample
    without the lens, view effects and their noise included: the lens's draws shift none of them."""
    config = small_config(**EVERYTHING, **ZERO_LENS, lens_lambda=(0, 0), lens_model=model)
    for index in range(2):
        lens = SidarDataset(None, config, seed=4).sample(index)
        plain = SidarDataset(None, config.replace(lens_model="none"), seed=4).sample(index)
        assert torch.equal(lens.pop("lens"), torch.zeros(3, 5, dtype=torch.float64))
        assert lens.pop("lens_model") == model
        assert_same_sample(lens, plain)


@pytest.mark.gl
def test_nothing_is_paid_without_a_lens():
    config = small_config()
    dataset = SidarDataset(None, config, seed=1)
    rng = dataset.generator(0)
    painting = dataset.source.painting(0, config.image_size)
    with collect_timings() as timings:
        render_arrays(dataset.renderer(), sample_sequence(config, rng), painting, config, 0, rng=rng)
    assert "lens" not in timings and timings["colour"] > 0
    with_lens = config.replace(lens_model="division")
    rng = dataset.generator(0)
    with collect_timings() as timings:
        render_arrays(dataset.renderer(), sample_sequence(with_lens, rng), painting, with_lens, 0, rng=rng)
    assert timings["lens"] > 0


def grid_sample_reference(rendered, maps, canvas):
    """Every per-view plane of ``rendered`` (a render over ``canvas``, no lens) resampled at the exact ``maps``
    (V, H, W, 2) by torch's ``grid_sample`` (bilinear, border padding) from each view's window, levels rounded,
    masks and background cut at 1/2: the CPU lens step of commit dfa9337 and before, at exact maps."""
    names = sorted(rendered.outputs)
    out = {key: [] for key in ("views", "masks", "background", *names)}
    for i, view_maps in enumerate(maps):
        h, w = canvas.window(i)
        planes = [rendered.views[i], rendered.masks[i][..., None], rendered.background[i][..., None],
                  *(rendered.outputs[name][i].reshape(*rendered.masks.shape[1:], -1) for name in names)]
        channels = torch.cat([torch.from_numpy(p[:h, :w].astype(np.float32)).permute(2, 0, 1) for p in planes])
        grid = torch.from_numpy(view_maps - canvas.origins[i]) * torch.tensor([2 / (w - 1), 2 / (h - 1)]) - 1
        r = torch.nn.functional.grid_sample(channels[None], grid[None].float(), mode="bilinear", padding_mode="border",
                                            align_corners=True)[0]
        out["views"].append(r[:3].round().permute(1, 2, 0).numpy().astype(np.uint8))
        out["masks"].append((r[3] >= 0.5).numpy())
        out["background"].append((r[4] >= 0.5).numpy())
        start = 5
        for name in names:
            c = rendered.outputs[name].shape[-1] if rendered.outputs[name].ndim == 4 else 1
            levels = r[start:start + c].round().permute(1, 2, 0).numpy().astype(np.uint8)
            out[name].append(levels[..., 0] if rendered.outputs[name].ndim == 3 else levels)
            start += c
    return {key: np.stack(arrays) for key, arrays in out.items()}


@pytest.mark.gl
@pytest.mark.parametrize("model", ["brown_conrady", "division"])
def test_the_gl_resampling_is_grid_sample_at_the_exact_maps(model):
    """The renderer's resampling pass (``render.resample``) against ``grid_sample`` of the same canvas render at
    the exact float64 maps: views and optional outputs within 1 level (float32 sources and float weights: on
    under 0.05 % of the pixels), masks and background the same but for under 0.05 % of their pixels."""
    from sidar_torch.render.resample import LensResampling
    from sidar_torch.sample.lens_views import distortion_maps, lens_canvas

    config = load_config("misaligned", image_size=(96, 128), n_views=3, lens_model=model, opacity_output=True,
                         shadow_free_output=True, shadow_mask_output=True, n_occluders=(2, 3))
    dataset = SidarDataset(None, config, seed=1)
    renderer = dataset.renderer()
    for index in range(2):
        sequence = dataset.scene(index)
        painting = dataset.source.painting(index, config.image_size)
        lens = LensResampling.of(sequence)
        canvas = lens_canvas(lens.border)
        bent = renderer.render(sequence, painting, canvas=canvas, lens=lens)
        expected = grid_sample_reference(renderer.render(sequence, painting, canvas=canvas),
                                         distortion_maps(model, lens.lenses, lens.K, config.image_size), canvas)
        got = {"views": bent.views, "masks": bent.masks, "background": bent.background, **bent.outputs}
        assert got.keys() == expected.keys()
        for name, array in expected.items():
            assert got[name].shape == array.shape and got[name].dtype == array.dtype, name
            diff = np.abs(got[name].astype(int) - array.astype(int))
            assert diff.max() <= 1 and (diff > 0).mean() < 5e-4, (name, diff.max(), (diff > 0).mean())


def brown_pairs(count=2, size=(192, 256)):
    """``(with the lens, without)`` arrays of ``count`` samples of misaligned through Brown-Conrady lenses,
    of built-in paintings softened by a Gaussian of 1 px (their 2-pixel grain is beyond what two bilinear
    resamplings keep; edges and shapes, which a wrong geometry moves, stay)."""
    config = load_config("misaligned", image_size=size, n_views=3, lens_model="brown_conrady", lens_k1=(-0.1, -0.06),
                         lens_k2=(0.0, 0.03))
    source = SidarDataset(None, config).source
    paintings = [np.array(Image.fromarray(source.painting(i, size)).filter(ImageFilter.GaussianBlur(1)))
                 for i in range(count)]
    return [(SidarDataset(paintings, config, seed=2).sample_arrays(i),
             SidarDataset(paintings, config.replace(lens_model="none"), seed=2).sample_arrays(i)) for i in range(count)]


@pytest.mark.gl
def test_cv2_undistort_of_a_brown_conrady_view_is_the_same_scene_without_the_lens():
    """OpenCV's own undistortion of each rendered view equals the pinhole render at >= 35 dB on the
    painting's pixels 8 px away from the border and from where the painting ends (both resamplings
    blur: two bilinear steps)."""
    cv2 = pytest.importorskip("cv2")
    for lens, plain in brown_pairs():
        for v in range(len(lens.images)):
            K, dist = lens.K[v], lens.lens[v]
            undone = cv2.undistort(lens.images[v], K, dist)
            h, w = plain.masks[v].shape
            mx, my = cv2.initUndistortRectifyMap(K, dist, None, K, (w, h), cv2.CV_32FC1)
            keep = cv2.erode((plain.masks[v] == 0).astype(np.uint8), np.ones((17, 17), np.uint8)) > 0
            keep &= (mx >= 8) & (mx <= w - 9) & (my >= 8) & (my <= h - 9)
            assert keep.sum() > 1000
            undone_psnr = psnr(undone[keep], plain.images[v][keep])
            assert undone_psnr >= 35, (v, dist)
            assert psnr(lens.images[v][keep], plain.images[v][keep]) < undone_psnr - 3  # the lens did bend the view


@pytest.mark.gl
def test_cv2_undistort_points_of_the_distorted_corners_land_on_the_pinhole_corners():
    """The painting's corners through the lens, undistorted by OpenCV, land on the pinhole corners
    within 0.05 px; the rendered ``distortion_maps`` are OpenCV's undistortion of every pixel."""
    cv2 = pytest.importorskip("cv2")
    config = load_config("misaligned", image_size=(96, 128), n_views=3, lens_model="brown_conrady",
                         distortion_map_output=True)
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)
    for index in range(2):
        s = SidarDataset(None, config, seed=9).sample_arrays(index)
        for v in range(3):
            K, dist = s.K[v], s.lens[v]
            corners = project(K[None], s.R[v][None], s.t[v][None], plane_corners(config.image_size))[0]
            bent = distorted_points("brown_conrady", dist, K, corners)
            back = cv2.undistortPoints(bent[:, None], K, dist, R=None, P=K, criteria=criteria)[:, 0]
            assert np.abs(back - corners).max() < 0.05
            pixels = np.stack(np.meshgrid(np.arange(0, 128, 7.0), np.arange(0, 96, 7.0)), -1).reshape(-1, 2)
            sources = cv2.undistortPoints(pixels[:, None], K, dist, R=None, P=K, criteria=criteria)[:, 0]
            maps = s.distortion_maps[v][:, pixels[:, 1].astype(int), pixels[:, 0].astype(int)].T
            assert np.abs(maps - sources).max() < 0.05


@pytest.mark.gl
def test_every_per_view_image_is_distorted_alike_and_undistort_returns_the_pinhole_views():
    config = load_config("misaligned", image_size=(192, 256), n_views=3, lens_model="brown_conrady",
                         lens_k1=(-0.1, -0.06), opacity_output=True, shadow_free_output=True)
    lens = SidarDataset(None, config, seed=2).sample(0)
    plain = SidarDataset(None, config.replace(lens_model="none"), seed=2).sample(0)
    assert set(lens["masks"].unique().tolist()) <= {0.0, 1.0}
    assert torch.equal(lens["label"], plain["label"]) and torch.equal(lens["homographies"], plain["homographies"])
    # Masks and opacities are bent alike: a masked pixel is partly hidden (opacity above 0) through the
    # lens as without it, and an unobstructed one (opacity 0) unmasked.
    for sample in (plain, lens):
        assert bool((sample["opacities"][sample["masks"] == 1] > 0).all())
        assert bool((sample["masks"][sample["opacities"] == 0] == 0).all())
    back = undistort(lens, "brown_conrady")
    inner = (slice(None), slice(None), slice(12, -12), slice(12, -12))
    agree = (back["masks"][inner] == plain["masks"][inner]).float().mean()
    assert agree > 0.98 and back["images"].shape == plain["images"].shape
    seen = (plain["masks"][inner] == 0) & (back["masks"][inner] == 0)
    diff = (back["images"][inner] - plain["images"][inner]).abs().mul(255)
    assert psnr(np.zeros(1), diff.expand(-1, 3, -1, -1)[seen.expand(-1, 3, -1, -1)].numpy()) >= 30
    assert lens["lens_model"] == "brown_conrady" and "lens_model" not in plain
    for name in back:  # the sample's own lens_model, by default
        assert torch.equal(undistort(lens)[name], back[name]), name
    with pytest.raises(ValueError, match="sample: expected a sample rendered through a lens"):
        undistort(plain, "brown_conrady")
    with pytest.raises(ValueError, match="lens_model: expected one of"):
        undistort(lens, "none")


def synthetic_lens_sample(model, n_views=2, size=(24, 32), seed=0):
    """A sample dict of random views through ``model`` lenses of -0.2 at the image's corner (barrel),
    without rendering."""
    rng = np.random.default_rng(seed)
    K = np.array([[30.0, 0, 15.5], [0, 30, 11.5], [0, 0, 1]])
    corner = {"brown_conrady": [-0.2, 0, 0, 0, 0], "division": [-0.2, 0, 0, 0, 0]}[model]
    lens = scaled_lens(model, np.array(corner), K, size)
    return {"images": torch.from_numpy(rng.random((n_views, 3, *size), np.float32)),
            "masks": torch.zeros(n_views, 1, *size), "K": torch.from_numpy(np.stack([K] * n_views)).float(),
            "lens": torch.from_numpy(np.stack([lens] * n_views)), "lens_model": model}


def test_undistort_takes_the_samples_lens_model_and_refuses_a_contradicting_one_by_name():
    """Issue 48: ``undistort(sample, "brown_conrady")`` of a division-lens sample returned wrong views
    and no error. The same coefficients undistort differently by model, so the model matters."""
    division = synthetic_lens_sample("division")
    as_brown = undistort({**division, "lens_model": "brown_conrady"})
    by_sample = undistort(division)
    assert torch.equal(by_sample["images"], undistort(division, "division")["images"])
    assert not torch.equal(by_sample["images"], as_brown["images"])
    with pytest.raises(ValueError, match="lens_model: 'brown_conrady' contradicts the sample's lens_model 'division'"):
        undistort(division, "brown_conrady")
    without = {key: value for key, value in division.items() if key != "lens_model"}
    assert torch.equal(undistort(without, "division")["images"], by_sample["images"])
    with pytest.raises(ValueError, match="lens_model: the sample records no lens_model"):
        undistort(without)
    with pytest.raises(ValueError, match=r"sample\['lens_model'\]: expected one of \['brown_conrady', 'division'\]"):
        undistort({**division, "lens_model": "fisheye"})


def test_undistort_of_a_batch_takes_each_samples_lens_model():
    """A DataLoader batch (``stack_samples``): ``lens_model`` a list of B strings, each its sample's."""
    samples = [synthetic_lens_sample("division", seed=0), synthetic_lens_sample("brown_conrady", seed=1)]
    batch = stack_samples(samples)
    assert batch["lens_model"] == ["division", "brown_conrady"]
    assert batch["lens_model"] == torch.utils.data.default_collate(samples)["lens_model"]
    back = undistort(batch)
    for b, sample in enumerate(samples):
        assert torch.equal(back["images"][b], undistort(sample)["images"])
    with pytest.raises(ValueError, match="lens_model: 'division' contradicts the sample's lens_model 'brown_conrady'"):
        undistort(batch, "division")


@pytest.mark.gl
def test_an_export_through_a_lens_reads_back_as_rendered(tmp_path):
    config = small_config(lens_model="division", distortion_map_output=True, opacity_output=True)
    dataset = SidarDataset(None, config, seed=3)
    for layout, shard_size in (("folders", None), ("shards", 2)):
        export_dataset(dataset, tmp_path / layout, count=2, shard_size=shard_size, progress=False)
        read = ExportedDataset(tmp_path / layout)
        for index in range(2):
            assert read[index]["lens_model"] == "division"  # the model read back, which undistort takes
            assert_same_sample(read[index], dataset.sample(index))


def reference_pair_results(samples, solver):
    """Per reference pair (view 0, view j) of each sample: homlib's two-sided division-model solver on
    SIFT matches of the distorted views, in normalised coordinates; ``(corner error px, worst relative
    lambda error)``."""
    cv2, homlib = pytest.importorskip("cv2"), pytest.importorskip("homlib")
    sift = cv2.SIFT_create(contrastThreshold=0.01)
    results = []
    for s in samples:
        h, w = s.images.shape[1:3]
        features = [sift.detectAndCompute(cv2.cvtColor(image, cv2.COLOR_RGB2GRAY), None) for image in s.images]
        for j in range(1, len(s.images)):
            (k0, d0), (kj, dj) = features[0], features[j]
            matches = [a for a, b in cv2.BFMatcher().knnMatch(d0, dj, k=2) if a.distance < 0.75 * b.distance]
            x = np.array([k0[m.queryIdx].pt for m in matches])
            y = np.array([kj[m.trainIdx].pt for m in matches])
            options = homlib.LORansacOptions()
            options.squared_inlier_threshold = (1.0 / s.K[0, 0, 0]) ** 2
            options.final_least_squares = True
            normalised = [((p - K[:2, 2]) / np.diag(K)[:2]).T.copy() for p, K in ((x, s.K[0]), (y, s.K[j]))]
            pose, _ = getattr(homlib, solver)(*normalised, options)
            H = s.K[j] @ pose.homography @ np.linalg.inv(s.K[0])
            corners = np.array([[0, 0, 1], [w - 1, 0, 1], [w - 1, h - 1, 1], [0, h - 1, 1]], float).T
            a, b = H @ corners, s.homographies[0, j] @ corners
            error = np.linalg.norm(a[:2] / a[2] - b[:2] / b[2], axis=0).max()
            lam = max(abs(pose.distortion_parameter / s.lens[0, 0] - 1), abs(pose.distortion_parameter2 / s.lens[j, 0] - 1))
            results.append((error, lam))
    return np.array(results)


@pytest.mark.gl
@pytest.mark.slow
def test_homlib_recovers_the_division_lenses_and_homographies_of_the_lens_preset():
    """``lomsac_kukelova_cvpr_2015_two_sided`` (both views are distorted, each with its own lambda) on
    SIFT matches of the reference pairs (view 0 to each other view) of the ``lens`` preset (768 x 1024):
    lambda within 10 % and the corners within 2 px on at least 80 % of the pairs. (At 384 x 512, SIFT's
    keypoints place lambda within 10 % on 11 of 20 such pairs: docs/lens.md.)"""
    config = load_config("lens")
    samples = [SidarDataset(None, config, seed=0).sample_arrays(i) for i in range(3)]
    results = reference_pair_results(samples, "lomsac_kukelova_cvpr_2015_two_sided")
    good = (results[:, 0] < 2) & (results[:, 1] < 0.1)
    assert good.mean() >= 0.8, results


@pytest.mark.gl
def test_the_snippet_of_the_lens_page_runs():
    page = (Path(__file__).resolve().parents[2] / "docs" / "lens.md").read_text()
    (code,) = re.findall(r"```python\n(.*?)```", page, re.S)
    scope = {}
    exec(code, scope)
    assert scope["sample"]["lens"].shape == (3, 5) and scope["pinhole"]["images"].shape == (3, 3, 192, 256)
    assert scope["sample"]["lens_model"] == "division"


@pytest.mark.gl
def test_sidar_augment_and_homography_pairs_carry_the_lens():
    from sidar_torch import SidarAugment, homography_pairs

    augment = SidarAugment("misaligned", n_views=3, image_size=(48, 64), seed=0, lens_model="division")
    batch = augment(torch.rand(2, 3, 48, 64, generator=torch.Generator().manual_seed(0)))
    assert batch["lens"].shape == (2, 3, 5) and batch["lens"].dtype == torch.float64
    assert bool((batch["lens"][..., 0] != 0).all()) and bool((batch["lens"][..., 1:] == 0).all())
    assert batch["lens_model"] == ["division", "division"]
    pairs = homography_pairs(batch, 16, generator=torch.Generator().manual_seed(0))
    a, b = pairs["views"].unbind(1)
    assert torch.equal(pairs["lens_a"], batch["lens"][torch.arange(2), a])
    assert torch.equal(pairs["lens_b"], batch["lens"][torch.arange(2), b])


EDGE_OF_FOLDING = dict(lens_model="brown_conrady", lens_k2=(0.0, 0.0), lens_k3=(0.0, 0.0), lens_p1=(0.01, 0.01),
                       lens_p2=(0.01, 0.01))
"""Ranges of a barrel whose tangential terms bring it to the edge of folding (k1 r^2 = -0.12003 with them, -0.148
without): with lens_k1 = (-0.12, -0.12) just inside."""


def test_the_renderer_refuses_by_the_configs_test_exactly_the_lenses_that_fold():
    """``LensResampling.of`` (at render time) refuses a lens iff ``choices.lenses.lens_folds`` (what the config
    checks its ranges with) says it folds at the view's corner; near the edge of folding and over the fields'
    bounds, at 768 x 1024, the pass's Newton steps settle for every lens that does not fold."""
    import dataclasses

    from sidar_torch.choices.lenses import corner_coefficients, lens_folds
    from sidar_torch.render.resample import LensResampling

    config = load_config("misaligned", image_size=(768, 1024), n_views=2, lens_model="brown_conrady")
    sequence = sample_sequence(config, np.random.default_rng(0))
    K = sequence.cameras()[0]
    rng = np.random.default_rng(5)
    edge = [(-0.12, 0.0, 0.01, 0.01, 0.0), (-0.1201, 0.0, 0.01, 0.01, 0.0), (-0.1479, 0.0, 0.0, 0.0, 0.0),
            (-0.148, 0.0, 0.0, 0.0, 0.0), (-0.14, 0.0, 0.01, 0.01, 0.0), (-0.14, 0.0, 0.002, -0.002, 0.0)]
    drawn = [np.concatenate([rng.uniform(-0.5, 0.5, 2), rng.uniform(-0.01, 0.01, 2), rng.uniform(-0.5, 0.5, 1)])
             for _ in range(60)]
    refused = 0
    for corner in [*edge, *drawn]:
        lenses = np.stack([scaled_lens("brown_conrady", np.array(corner), k, config.image_size) for k in K])
        at_corner = np.stack([corner_coefficients("brown_conrady", lens, k, config.image_size) for lens, k in zip(lenses, K)])
        changed = dataclasses.replace(sequence, lenses=lenses)
        if lens_folds("brown_conrady", at_corner).any():
            refused += 1
            with pytest.raises(ValueError, match=r"lenses: brown_conrady .* fold their view.*choices\.lenses\.lens_folds"):
                LensResampling.of(changed)
        else:
            assert (LensResampling.of(changed).steps > 0).all(), corner
    assert 10 < refused < 50
    assert load_config("misaligned", **EDGE_OF_FOLDING, lens_k1=(-0.12, -0.12)).lens_k1 == (-0.12, -0.12)
    with pytest.raises(ValueError, match=r"lens_k1=\(-0.1201, -0.1201\).*the tangential terms fold it"):
        load_config("misaligned", **EDGE_OF_FOLDING, lens_k1=(-0.1201, -0.1201))


@pytest.mark.gl
def test_a_lens_just_inside_the_edge_of_folding_renders():
    """The config the edge lets through renders: finite views of the painting with binary masks, whose
    distortion maps send every distorted pixel back to itself through the lens."""
    config = load_config("misaligned", image_size=(48, 64), n_views=2, distortion_map_output=True, **EDGE_OF_FOLDING,
                         lens_k1=(-0.12, -0.12))
    sample = {key: value.numpy() if torch.is_tensor(value) else value
              for key, value in SidarDataset(None, config, seed=0).sample(0).items()}
    assert sample["images"].shape == (2, 3, 48, 64) and np.isfinite(sample["images"]).all()
    assert set(np.unique(sample["masks"])) <= {0, 1} and (sample["masks"] == 0).any()
    grid = np.stack(np.meshgrid(np.arange(64.0), np.arange(48.0)), -1)
    for lens, k, maps in zip(sample["lens"], sample["K"], sample["distortion_maps"]):
        back = distorted_points("brown_conrady", lens, k, maps.transpose(1, 2, 0).astype(np.float64))
        assert np.abs(back - grid).max() < 1e-2


EXACT_SIZE = (768, 1024)
"""The lens preset's size, at which the exact maps are checked pixel by pixel."""


def exact_intrinsics(size=EXACT_SIZE, fov_degrees=80.0):
    h, w = size
    f = 0.5 * w / np.tan(np.radians(fov_degrees) / 2)
    return np.array([[f, 0, (w - 1) / 2], [0, f, (h - 1) / 2], [0, 0, 1.0]])


def accepted_brown_conrady_corners(n, seed, low=(-0.5, -0.5, -0.01, -0.01, -0.5), high=(0.5, 0.5, 0.01, 0.01, 0.5)):
    """``(n, 5)`` Brown-Conrady coefficients at the corner, uniform within ``low``-``high`` (default: the config's
    bounds), that ``lens_folds`` accepts."""
    draws = np.random.default_rng(seed).uniform(low, high, (20 * n, 5))
    return draws[~lens_folds("brown_conrady", draws)][:n]


def assert_exact_maps(corners):
    """Every pixel's exact source (``distortion_maps``) distorts back onto it within 1e-6 px (Newton's tolerance is
    under 2e-6 px), and the sources of neighbouring pixels lie under 1 / LEAST_SLOPE = 20 px apart (the inverse's
    Jacobian bound of a lens that does not fold: a root beyond a fold would jump)."""
    K = exact_intrinsics()
    grid = np.stack(np.meshgrid(np.arange(EXACT_SIZE[1], dtype=float), np.arange(EXACT_SIZE[0], dtype=float)), -1)
    for corner in corners:
        lens = scaled_lens("brown_conrady", corner, K, EXACT_SIZE)
        maps = distortion_maps("brown_conrady", lens[None], K[None], EXACT_SIZE)[0]
        back = np.abs(distorted_points("brown_conrady", lens, K, maps) - grid).max()
        assert back < 1e-6, (corner.tolist(), back)
        jump = max(np.abs(np.diff(maps, axis=0)).max(), np.abs(np.diff(maps, axis=1)).max())
        assert jump < 1 / LEAST_SLOPE, (corner.tolist(), jump)


def test_the_exact_maps_of_strong_pincushions_with_negative_k3_return_every_pixel():
    # Newton's method from the distorted point (up to 79fbdc3) left these pixels 0.7 px to 1e12 px off, silently.
    assert_exact_maps(np.array([[0.473, 0.083, 0, 0, -0.446], [0.321, 0.07, -0.002, -0.002, -0.38],
                                [0.449, 0.136, -0.008, -0.004, -0.486], [0.334, 0.194, 0.001, -0.005, -0.499],
                                [0.256, 0.26, 0.003, -0.004, -0.456]]))


def test_the_exact_maps_of_random_accepted_lenses_return_every_pixel():
    # the config's bounds, tangential terms included; then strong pincushions with negative k3, the hardest.
    assert_exact_maps(accepted_brown_conrady_corners(12, seed=11))
    assert_exact_maps(accepted_brown_conrady_corners(12, seed=12, low=(0.2, -0.5, -0.01, -0.01, -0.5),
                                                     high=(0.5, 0.5, 0.01, 0.01, -0.2)))


def test_an_unconverged_exact_inverse_raises_naming_the_lens_and_its_residual(monkeypatch):
    K = exact_intrinsics()
    corner = np.array([0.473, 0.083, 0, 0, -0.446])
    lens = scaled_lens("brown_conrady", corner, K, EXACT_SIZE)
    monkeypatch.setattr(lenses, "NEWTON_STEPS", 1)
    with pytest.raises(ValueError, match=r"lens: brown_conrady \[.*\] \(normalised coordinates\) left a residual "
                                         r"of .* after 1 Newton steps, over NEWTON_TOLERANCE 1e-10"):
        distortion_maps("brown_conrady", lens[None], K[None], EXACT_SIZE)
    monkeypatch.undo()
    # a lens that folds before the image's corner (set by hand: the config refuses it) has no source there
    folding = np.array([-0.3, 0, 0, 0, 0])
    assert lens_folds("brown_conrady", folding)
    corners = np.array([[0.0, 0.0], [EXACT_SIZE[1] - 1.0, EXACT_SIZE[0] - 1.0]])
    with pytest.raises(ValueError, match="left a residual of"):
        undistorted_points("brown_conrady", scaled_lens("brown_conrady", folding, K, EXACT_SIZE), K, corners)
