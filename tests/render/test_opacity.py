"""The soft ``opacities`` output, proved by rendering: it is the fraction of the painting the colour
draw hides, it agrees with ``masks`` where both are binary, and switching it on changes nothing else."""

import numpy as np
import pytest
import torch
from PIL import Image

from sidar_torch import ExportedDataset, SidarAugment, SidarDataset, export_dataset, geometry, load_config
from sidar_torch.render.gpu import PaintingTexture
from sidar_torch.scene import Camera, Material, Occluder

from conftest import SMALL, TINY, assert_same_sample, render_flat_painting, sample_digest, small_config
from test_render import cube

pytestmark = pytest.mark.gl  # renders

H, W = SMALL
OPAQUE_KINDS = ("diffuse", "glossy", "metallic", "principled")


def render(occluders, painting=200, mask_min_opacity=0.0, camera=None, visible=True):
    """One unlit (ambient 1, no lights) view of a flat grey painting, with its opacities."""
    out = render_flat_painting(occluders, ambient=1.0, painting=painting, camera=camera, occluders_visible=visible,
                               mask_min_opacity=mask_min_opacity, outputs=frozenset({"opacities"}))
    return out.views[0].astype(int), out.masks[0], out.outputs["opacities"][0].astype(int)


def dark_glass(alpha):
    """Black, no specular: in an unlit view it only takes away ``alpha`` (and Fresnel) of the painting."""
    return Material(np.array([0.0, 0.0, 0.0, alpha]), 0.0, 1.0, specular=0.0)


def sphere(material, radius=0.15, height=0.3):
    return Occluder("sphere", np.array([0.0, 0.0, height]), np.eye(3), np.full(3, radius), material)


def test_opaque_occluders_give_opacities_equal_to_the_masks():
    config = small_config(occluder_materials=OPAQUE_KINDS, n_occluders=(2, 3), fov_deg=(90, 110))
    ds = SidarDataset(config=config.replace(opacity_output=True), seed=2)
    occluded = background = 0
    for index in range(2):
        sample = ds.sample(index)
        assert torch.equal(sample["opacities"], sample["masks"])
        occluded += int(((sample["masks"] == 1) & (sample["images"].amax(1, keepdim=True) > 0)).sum())
        background += int((sample["images"].amax(1, keepdim=True) == 0).sum())
    assert occluded > 100 and background > 100  # the draw ran over occluders and background


@pytest.mark.parametrize("alpha", [0.2, 0.5, 0.8])
def test_a_transparent_occluder_at_normal_incidence_hides_its_alpha_and_masks_follow_the_threshold(alpha):
    slab = cube([0.0, 0.0, 0.3], half=0.15, material=Material(np.array([0.2, 0.4, 0.9, alpha]), 0.0, 0.5))
    _, masked, opacity = render([slab])
    _, unmasked, same = render([slab], mask_min_opacity=0.9)
    fresnel = alpha + 0.04 * (1 - alpha)  # Schlick at normal incidence: 4 % reflectance
    assert abs(opacity[H // 2, W // 2] - 255 * fresnel) <= 1
    assert opacity[2, 2] == 0 and not masked[2, 2]  # beside it: the painting, unobstructed
    assert masked[H // 2, W // 2] and not unmasked.any()  # masks follow mask_min_opacity ...
    assert np.array_equal(opacity, same)  # ... the opacities do not


def test_opacities_are_what_the_colour_draw_hides_fresnel_rim_and_stacked_layers_included():
    # Unlit, a black glass leaves (1 - opacity) of the painting in the view, pixel for pixel.
    # A small sphere (about 14 px across) floats above the middle of a large one (about 29 px).
    spheres = [sphere(dark_glass(0.3), radius=0.2), sphere(dark_glass(0.5), radius=0.05, height=0.6)]
    view, mask, opacity = render(spheres)
    expected = (1 - opacity / 255) * 200
    assert np.abs(view[..., 0] - expected).max() <= 2
    rows = np.flatnonzero(mask[:, W // 2])
    single = opacity[H // 2 + 18, W // 2]  # the large sphere only
    assert opacity[rows[1], W // 2] > single + 20  # grazing rim: Fresnel makes it more opaque
    assert opacity[H // 2, W // 2] > single + 40  # two layers: 1 - (1 - a1)(1 - a2)


def test_background_is_fully_hidden_and_occluder_parts_behind_the_painting_do_not_count():
    camera = Camera(geometry.intrinsics_from_fov(120, SMALL), *geometry.look_at(np.array([0.0, 0.0, 0.5])))
    # A sphere sunk into the painting: only its cap above it is seen (the masks are tested to
    # leave out parts behind the painting); its silhouette from the camera is wider than the cap.
    _, mask, opacity = render([sphere(dark_glass(0.5), height=-0.1)], camera=camera)
    assert mask[0, 0] and opacity[0, 0] == 255 and opacity[-1, -1] == 255
    assert np.array_equal(opacity > 0, mask)
    assert ((opacity > 0) & (opacity < 255)).sum() > 20  # the cap, seen through


def test_shadow_only_occluders_hide_nothing():
    _, mask, opacity = render([sphere(dark_glass(0.5))], visible=False)
    assert not mask.any() and not opacity.any()


def test_switching_opacities_on_changes_no_other_key_and_is_deterministic():
    config = small_config(occluder_materials=("transparent", "glass", "diffuse"), n_occluders=(2, 3))
    off, on = SidarDataset(config=config, seed=4), SidarDataset(config=config.replace(opacity_output=True), seed=4)
    soft = 0
    for index in range(2):
        plain, with_opacities = off.sample(index), on.sample(index)
        assert "opacities" not in plain
        digests = sample_digest(with_opacities)
        assert digests.pop("opacities") == sample_digest(on.sample(index))["opacities"]
        assert digests == sample_digest(plain)
        opacities, masks = with_opacities["opacities"], with_opacities["masks"]
        assert opacities.shape == masks.shape and opacities.dtype == torch.float32
        assert torch.equal(opacities[masks == 0], torch.zeros_like(opacities[masks == 0]))  # visible painting
        soft += int(((opacities > 0) & (opacities < 1)).sum())
    assert soft > 50  # transparent occluders were seen


def test_exported_opacities_read_back_byte_identical_in_both_layouts(tmp_path):
    config = load_config("misaligned", **TINY, occluder_materials=("transparent",), n_occluders=(2, 3),
                         opacity_output=True)
    ds = SidarDataset(config=config, seed=3)
    export_dataset(ds, tmp_path / "folders", count=2, progress=False)
    export_dataset(ds, tmp_path / "shards", count=2, shards=2, progress=False)
    samples = [ds.sample(index) for index in range(2)]
    for layout in ("folders", "shards"):
        read = ExportedDataset(tmp_path / layout)
        assert read.indices == [0, 1]
        for k in range(2):
            assert_same_sample(read[k], samples[k])
    png = np.array(Image.open(tmp_path / "folders" / "000001" / "1-o.png"))
    opacities = samples[1]["opacities"][1, 0]
    assert png.dtype == np.uint8 and torch.equal(torch.from_numpy(png).float() / 255, opacities)
    assert ((opacities > 0) & (opacities < 1)).any()
    plain = SidarDataset(config=config.replace(opacity_output=False), seed=3)
    export_dataset(plain, tmp_path / "plain", count=1, progress=False)
    assert not list((tmp_path / "plain" / "000000").glob("*-o.png")) and "opacities" not in ExportedDataset(
        tmp_path / "plain")[0]


def test_augment_batches_opacities_only_when_asked():
    images = torch.rand(2, 3, 40, 50, generator=torch.Generator().manual_seed(0))
    kwargs = dict(image_size=SMALL, n_views=2, n_occluders=(1, 2), seed=0)
    soft = SidarAugment("misaligned", opacity_output=True, **kwargs)(images)
    plain = SidarAugment("misaligned", **kwargs)(images)
    assert "opacities" not in plain and soft["opacities"].shape == (2, 2, 1, *SMALL)
    assert all(torch.equal(soft[key], plain[key]) for key in plain)


def test_a_bad_switch_value_raises_naming_the_field():
    with pytest.raises(ValueError, match="opacity_output"):
        load_config("misaligned", opacity_output="yes")


def test_the_opacity_draw_keeps_the_painting_uploaded(monkeypatch):
    # The opacity draw uses no texture; the renderer must not free the painting's and upload it
    # again for the next view (pixels would not change, only the time).
    config = small_config(n_views=3, n_occluders=(2, 3), opacity_output=True)
    dataset = SidarDataset(config=config, seed=9)
    dataset.warm_up()  # its grey painting is uploaded before counting (the test passes in any order)
    uploads = []
    upload = PaintingTexture.upload
    monkeypatch.setattr(PaintingTexture, "upload", lambda t: (upload(t) and uploads.append(t)) or False)
    dataset.sample(0)
    assert len(uploads) == 1  # the painting, once
