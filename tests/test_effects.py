"""View effects beyond the paper (issue 5, item 7): background, exposure/gamma, sensor noise, JPEG.

Each effect is shown by rendering a sample with it and without it (same seed): it changes the
views as claimed, and nothing else of the sample.
"""

import io

import numpy as np
import pytest
import torch
from PIL import Image

from sidar_torch import SidarAugment, SidarDataset, geometry
from sidar_torch.sample.effects import (ViewEffects, apply_effects, blur_painting, draw_effects, gaussian_filter,
                                        linear_to_srgb, srgb_to_linear)
from sidar_torch.sample import render_sample
from sidar_torch.render import RenderSettings, shared_renderer
from sidar_torch.scene import Camera, Material, Occluder, SceneSequence, ViewScene, sample_sequence

from conftest import SMALL, sample_digest, small_config, textured_painting

pytestmark = pytest.mark.gl  # renders

H, W = SMALL
ALL_ON = dict(background="view", background_level=(0.2, 1.0), exposure_jitter=True, sensor_noise=True,
              jpeg=True, pixel_filter_sigma=0.85)
SCENE_KEYS = ("masks", "label", "homographies", "K", "R", "t", "homography_error")


def flat_painting(top, bottom=None):
    """A ``(1, 3, H, W)`` painting of grey level ``top`` (0-255) above ``bottom`` (default ``top``)."""
    levels = torch.full((1, 3, H, W), top / 255)
    levels[..., H // 2:, :] = (top if bottom is None else bottom) / 255
    return levels


def pair(index=0, source=None, preset="misaligned", scene=None, **effects):
    """Sample ``index`` of one seed, of ``preset`` with the ``scene`` overrides, without and with ``effects``."""
    off = SidarDataset(source, small_config(preset, **(scene or {})), seed=3).sample(index)
    on = SidarDataset(source, small_config(preset, **(scene or {}), **effects), seed=3).sample(index)
    return off, on


def linear(images):
    """``(..., 3, H, W)`` float views in [0, 1] to linear light, float64."""
    return srgb_to_linear(images.double())


def test_srgb_curves_are_exact_inverses_on_the_8_bit_grid():
    levels = torch.arange(256, dtype=torch.float32) / 255
    assert torch.equal((linear_to_srgb(srgb_to_linear(levels)) * 255).round(), levels * 255)
    assert abs(float(srgb_to_linear(torch.tensor(0.5))) - 0.21404) < 1e-5  # the sRGB standard's values
    assert abs(float(linear_to_srgb(torch.tensor(0.18))) - 0.46135) < 1e-5


def test_effects_are_off_by_default_and_leave_the_views_bit_identical():
    config = small_config()
    assert draw_effects(config, 3, SMALL, None) is None
    dataset = SidarDataset(None, config, seed=1)
    rng = dataset.generator(0)
    sequence = sample_sequence(config, rng)
    painting = dataset.source.painting(0, SMALL)
    raw = dataset.renderer().render(sequence, painting).views
    state = rng.bit_generator.state
    sample = render_sample(dataset.renderer(), sequence, painting, config, 0, rng=rng)
    assert rng.bit_generator.state == state  # effects off draw nothing
    assert torch.equal(sample["images"], torch.from_numpy(raw).permute(0, 3, 1, 2).float() / 255)
    assert torch.equal(sample["images"], dataset.sample(0)["images"])


def test_switching_every_effect_on_changes_the_views_only():
    off, on = pair(scene={"n_occluders": (2, 3)}, **ALL_ON)
    for key in SCENE_KEYS:
        assert sample_digest(off)[key] == sample_digest(on)[key], key
    assert (on["images"] - off["images"]).abs().mean(dim=(1, 2, 3)).min() > 0.01  # every view changed
    again = SidarDataset(None, small_config(**ALL_ON, n_occluders=(2, 3)), seed=3).sample(0)
    assert sample_digest(again) == sample_digest(on)  # deterministic


def test_sensor_noise_std_is_the_configured_read_noise_in_linear_light():
    off, on = pair(source=flat_painting(60, 200), preset="ambient", scene={"aligned": True},
                   sensor_noise=True, read_noise=(0.02, 0.02), shot_noise=(0.0, 0.0))
    for half in (slice(0, H // 2), slice(H // 2, H)):  # flat under ambient light: only the noise varies
        assert off["images"][..., half, :].std(dim=(2, 3)).max() == 0
    noise = linear(on["images"]) - linear(off["images"])
    assert abs(float(noise.mean())) < 0.002
    assert float(noise.std()) == pytest.approx(0.02, rel=0.05)
    assert torch.equal(on["masks"], off["masks"]) and torch.equal(on["label"], off["label"])


def test_shot_noise_variance_grows_with_the_linear_intensity():
    k = 0.004
    off, on = pair(source=flat_painting(60, 200), preset="ambient", scene={"aligned": True},
                   sensor_noise=True, read_noise=(0.0, 0.0), shot_noise=(k, k))
    noise, clean = linear(on["images"]) - linear(off["images"]), linear(off["images"])
    for half in (slice(0, H // 2), slice(H // 2, H)):
        x = float(clean[..., half, :].mean())
        assert float(noise[..., half, :].var()) == pytest.approx(k * x, rel=0.1)  # Poisson: variance k x


def test_exposure_jitter_scales_the_linear_intensity_and_gamma_raises_it_to_a_power():
    brighter = {"exposure_jitter": True, "exposure_stops": (1.0, 1.0), "gamma": (1.0, 1.0)}
    off, on = pair(**brighter)
    x, y = linear(off["images"]), linear(on["images"])
    room = x < 0.45  # twice these stays below white
    assert int(room.sum()) > 1000
    # Rounding to 8 bits moves a value by at most 0.0045 in linear light (half a level where the
    # sRGB curve is steepest), and x's own rounding is doubled with it.
    assert float((y[room] - 2 * x[room]).abs().max()) < 0.012
    assert bool((y[x > 0.55] > 0.999).all())  # clipped at white, as a sensor saturates
    off, on = pair(exposure_jitter=True, exposure_stops=(0.0, 0.0), gamma=(2.0, 2.0))
    x, y = linear(off["images"]), linear(on["images"])
    assert float((y - x**2).abs().max()) < 0.015
    off, on = pair(exposure_jitter=True, exposure_stops=(-1.0, 1.0))
    gains = (linear(on["images"]).sum(dim=(1, 2, 3)) / linear(off["images"]).sum(dim=(1, 2, 3)))
    assert len({round(float(g), 3) for g in gains}) == 3  # a different exposure per view


def test_jpeg_output_is_a_pillow_round_trip_of_the_view():
    off, on = pair(jpeg=True, jpeg_quality=(40, 40))
    assert not torch.equal(on["images"], off["images"])
    for view, compressed in zip(off["images"], on["images"]):
        buffer = io.BytesIO()
        Image.fromarray((view.permute(1, 2, 0) * 255).round().byte().numpy()).save(buffer, "JPEG", quality=40)
        expected = torch.from_numpy(np.array(Image.open(buffer))).permute(2, 0, 1).float() / 255
        assert torch.equal(compressed, expected)
    _, finer = pair(jpeg=True, jpeg_quality=(95, 95))
    assert (finer["images"] - off["images"]).abs().mean() < (on["images"] - off["images"]).abs().mean()


def painting_pixels(sample, view):
    """``(H, W)`` bool: pixels of ``view`` whose centre the homography to view 0 (the painting's
    own pixel grid) sends into the painting grown by half a painting pixel, and into the painting
    shrunk by one (independent of ``sidar_torch.sample.effects``, which uses the cameras)."""
    v, u = np.mgrid[0:H, 0:W].astype(float)
    points = np.stack([u, v, np.ones_like(u)]).reshape(3, -1)
    mapped = sample["homographies"][view, 0].double().numpy() @ points
    centre = mapped[:, (H // 2) * W + W // 2]  # every camera looks at the painting's centre
    front = mapped[2] * centre[2] > 0
    x, y = mapped[:2] / mapped[2]
    near = front & (x >= -1) & (x <= W) & (y >= -1) & (y <= H)
    deep = front & (x >= 0.5) & (x <= W - 1.5) & (y >= 0.5) & (y <= H - 1.5)
    return near.reshape(H, W), deep.reshape(H, W)


@pytest.mark.parametrize("mode", ["view", "sequence"])
def test_background_pixels_take_the_colour_and_nothing_else_changes(mode):
    off, on = pair(index=2, scene={"n_occluders": (3, 3), "fov_deg": (95.0, 100.0)}, background=mode,
                   background_level=(0.2, 1.0))
    colours = []
    for view in range(1, 3):
        before, after = (s["images"][view].permute(1, 2, 0) for s in (off, on))
        masked = off["masks"][view, 0].bool()
        near, deep = painting_pixels(off, view)
        changed = (after != before).any(dim=2)
        assert 0 < int(changed.sum()) and not bool(changed[~masked].any())  # the visible painting is untouched
        assert not bool(changed[torch.from_numpy(deep)].any())  # occluders in front of the painting too
        assert bool((before[changed] == 0).all())  # only pixels the renderer left black
        empty = masked & (before == 0).all(dim=2) & torch.from_numpy(~near)
        assert bool(changed[empty].all())  # every empty pixel outside the painting
        assert bool((~(before == 0).all(dim=2) & masked).any())  # lit occluders, kept
        colour = after[changed].unique(dim=0)
        assert len(colour) == 1 and float(colour.min()) >= 0.2 - 1 / 510
        colours.append(colour)
    assert torch.equal(colours[0], colours[1]) == (mode == "sequence")
    for key in SCENE_KEYS:
        assert sample_digest(off)[key] == sample_digest(on)[key], key


def test_background_is_where_the_renderer_drew_nothing_even_beside_black_occluders():
    camera = Camera(geometry.intrinsics_from_fov(100, SMALL), *geometry.look_at(np.array([0.3, 0.2, 0.9])))
    edge = np.array([geometry.plane_size(SMALL)[0] / 2, 0.0, 0.1])  # a cube across the painting's right edge

    def drawn(rgb):
        cube = Occluder("cube", edge, np.eye(3), np.full(3, 0.15), Material(np.array([*rgb, 1.0]), 0.0, 1.0, 0.0))
        sequence = SceneSequence(SMALL, (ViewScene(camera, (), (cube,), Material(np.ones(4), 0.0, 1.0), 1.0),))
        return shared_renderer(RenderSettings(SMALL)).render(sequence, np.full((*SMALL, 3), 100, np.uint8))

    white, black = drawn((1, 1, 1)), drawn((0, 0, 0))
    nothing = (white.views[0] == 0).all(axis=2)  # a white cube and a grey painting: drawn pixels are not black
    on_black_cube = (black.views[0] == 0).all(axis=2) & ~nothing
    assert on_black_cube.sum() > 100 and nothing.sum() > 100
    assert np.array_equal(black.background[0], nothing)  # black occluder pixels are not background
    assert np.array_equal(white.background[0], nothing)


def test_apply_effects_with_identity_settings_changes_no_pixel():
    sample = SidarDataset(None, small_config(), seed=0).sample(0)
    views = (sample["images"].permute(0, 2, 3, 1) * 255).round().byte().numpy()
    masks = sample["masks"][:, 0].bool().numpy()
    one = np.ones(3)
    identity = ViewEffects(gain=one, gamma=one, read_noise=0 * one, shot_noise=0 * one,
                           noise=np.ones((3, H, W, 3), np.float32))
    assert np.array_equal(apply_effects(views, masks, identity), views)
    assert apply_effects(views, masks, None) is views


def test_augment_applies_the_effects_after_the_same_scenes():
    images = torch.rand(2, 3, 40, 50)
    off = SidarAugment(small_config(n_views=2), seed=4)(images)
    on = SidarAugment(small_config(n_views=2, jpeg=True, sensor_noise=True), seed=4)(images)
    assert torch.equal(on["masks"], off["masks"]) and torch.equal(on["homographies"], off["homographies"])
    assert not torch.equal(on["images"], off["images"])


def test_render_sample_without_a_generator_refuses_effects():
    config = small_config(jpeg=True)
    dataset = SidarDataset(None, config, seed=0)
    with pytest.raises(ValueError, match="rng.*jpeg"):
        render_sample(dataset.renderer(), dataset.scene(0), dataset.source.painting(0, SMALL), config, 0)


@pytest.mark.parametrize("field, value", [
    ("background", "white"), ("background", None), ("background_level", (0.5, 1.5)), ("exposure_jitter", "yes"),
    ("exposure_stops", (1.0, -1.0)), ("gamma", (0.0, 1.0)), ("sensor_noise", 1), ("read_noise", (-0.1, 0.1)),
    ("shot_noise", (0.0, 2.0)), ("jpeg", "on"), ("jpeg_quality", (0, 50)), ("jpeg_quality", (50.5, 60)),
    ("pixel_filter_sigma", -0.5), ("pixel_filter_sigma", 5.0), ("pixel_filter_sigma", float("nan")),
])
def test_bad_effect_values_raise_naming_the_field(field, value):
    with pytest.raises(ValueError, match=field):
        small_config(**{field: value})


def test_the_pixel_filter_keeps_flat_light_and_spreads_a_step_by_its_sigma():
    flat = torch.full((2, 20, 30, 3), 0.37)
    assert torch.allclose(gaussian_filter(flat, 0.85), flat, atol=1e-6)  # taps sum to one, borders reflected
    step = torch.zeros(1, 8, 200, 1)
    step[..., 100:, :] = 1.0
    profile = gaussian_filter(step, 1.5)[0, 4, :, 0].double()
    slope = profile.diff()  # the filter's own kernel, sampled: its spread is sigma
    x = torch.arange(len(slope), dtype=torch.float64)
    mean = (slope * x).sum() / slope.sum()
    assert abs(float(((slope * (x - mean) ** 2).sum() / slope.sum()).sqrt()) - 1.5) < 0.02
    assert float(profile[99] + profile[100]) == pytest.approx(1.0, abs=1e-6)  # symmetric about the edge


def test_the_pixel_filter_blurs_views_and_shadow_free_only_and_draws_nothing():
    scene = {"n_occluders": (2, 3), "shadow_free_output": True, "shadow_mask_output": True, "opacity_output": True}
    off, on = pair(scene=scene, pixel_filter_sigma=0.85)
    for key in (*SCENE_KEYS, "opacities", "shadow_masks"):
        assert sample_digest(off)[key] == sample_digest(on)[key], key
    for key in ("images", "shadow_free"):
        detail = [(s[key][:, :, 1:] - s[key][:, :, :-1]).abs().mean() for s in (off, on)]
        assert detail[1] < 0.8 * detail[0], key  # blurred: less pixel-to-pixel detail
    config = small_config(pixel_filter_sigma=0.85)
    effects = draw_effects(config, 3, SMALL, None)  # needs no generator: nothing is drawn
    assert effects == ViewEffects(blur_sigma=0.85)


def test_the_texture_blur_blurs_the_painting_in_the_views_not_the_label_masks_or_outlines():
    """``texture_blur_sigma`` blurs what the views see of the painting; the label stays the exact
    painting, and an occluder's outline against a flat painting stays as sharp as without it."""
    scene = {"n_occluders": (2, 3), "shadow_free_output": True, "opacity_output": True}
    off, on = pair(scene=scene, texture_blur_sigma=1.0)
    for key in (*SCENE_KEYS, "opacities"):
        assert sample_digest(off)[key] == sample_digest(on)[key], key
    painting = (on["masks"] == 0).expand_as(on["images"])
    for key in ("images", "shadow_free"):
        detail = [(s[key] * painting)[:, :, :, 1:].sub((s[key] * painting)[:, :, :, :-1]).abs().mean() for s in (off, on)]
        assert detail[1] < 0.8 * detail[0], key  # the painting blurred in the views
    flat = flat_painting(128)
    off, on = pair(source=flat, scene=scene, texture_blur_sigma=1.0)
    assert torch.equal(off["images"], on["images"])  # a flat painting: the outlines are untouched


def test_a_label_drawn_off_the_reference_camera_comes_from_the_exact_painting():
    cfg = small_config(n_views=2, n_occluders=(0, 0))
    seq = sample_sequence(cfg, np.random.default_rng(0))
    tilted = SceneSequence(seq.image_size, (seq.views[1], seq.views[0]))  # view 0 from a random camera: drawn
    painting = textured_painting(SMALL)
    renderer = shared_renderer(RenderSettings.from_config(cfg))
    exact = renderer.render(tilted, painting)
    blurred = renderer.render(tilted, painting, texture=blur_painting(painting, 1.0))
    assert np.array_equal(exact.label, blurred.label)
    assert not np.array_equal(exact.views, blurred.views)
    with pytest.raises(ValueError, match="texture: expected"):
        renderer.render(tilted, painting, texture=painting[:, :-1])


def test_blur_painting_keeps_a_flat_painting_and_spreads_a_texel_by_sigma_in_linear_light():
    assert np.array_equal(blur_painting(np.full((9, 11, 3), 77, np.uint8), 0.8), np.full((9, 11, 3), 77, np.uint8))
    dot = np.zeros((41, 41, 3), np.uint8)
    dot[20, 20] = 255
    light = srgb_to_linear(torch.from_numpy(blur_painting(dot, 2.0)[20, :, 0]).double() / 255)
    x = torch.arange(41, dtype=torch.float64) - 20
    assert float(((light * x ** 2).sum() / light.sum()).sqrt()) == pytest.approx(2.0, abs=0.1)
