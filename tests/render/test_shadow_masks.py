"""Shadow masks and shadow-free views (``shadow_mask_output``, ``shadow_free_output``), proved by
rendering the same scene with and without shadows: for a white Lambertian painting and no ambient
light, the view's linear luminance with shadows is ``1 - shadow_masks`` times the shadow-free one,
whatever the lights, their weights and the tints of transparent casters; and the shadow-free view is
the view itself wherever no shadow falls."""

from dataclasses import replace

import numpy as np
import pytest
import torch

from sidar_torch import ExportedDataset, SidarDataset, export_dataset, geometry
from sidar_torch.sample.effects import srgb_to_linear
from sidar_torch.render import RenderSettings, shared_renderer
from sidar_torch.scene import Camera, Light, Material, Occluder, SceneSequence, ViewScene
from sidar_torch.timing import collect_timings

from conftest import SMALL, small_config, LAMBERTIAN, render_flat_painting

pytestmark = pytest.mark.gl  # renders

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])


def spot(x, y, irradiance):
    position = np.array([x, y, 2.0])
    return Light("spot", position[None], np.ones(3), irradiance * float(position @ position), 0.6, 0.7)


def ball(at, rgba, radius=0.12, height=0.3):
    return Occluder("sphere", np.array([*at, height]), np.eye(3), np.full(3, radius),
                    Material(np.array(rgba), 0.0, 1.0, specular=0.0))


def render(occluders, lights, shadows=True):
    """A white painting through the reference camera: the rendered sequence (one view)."""
    with collect_timings() as timings:
        out = render_flat_painting(occluders, lights, LAMBERTIAN, painting=255, shadows=shadows,
                                   outputs=frozenset({"shadow_masks", "shadow_free"}))
    return out, timings


def luminance(image):
    return srgb_to_linear(torch.from_numpy(image / 255.0)).numpy() @ LUMINANCE


def test_the_shadow_mask_is_the_light_the_occluders_take_from_the_painting():
    lights = [spot(-1.0, 0.0, 0.5), spot(0.8, -0.6, 0.35)]
    casters = [ball((0.0, 0.0), [0.2, 0.3, 0.9, 1.0]), ball((0.35, 0.2), [0.9, 0.1, 0.1, 0.4])]  # opaque, red glass
    shadowed, _ = render(casters, lights)
    unshadowed, _ = render(casters, lights, shadows=False)
    fraction = shadowed.outputs["shadow_masks"][0] / 255.0
    seen = ~shadowed.masks[0] & (luminance(unshadowed.views[0]) > 0.05)
    assert (fraction[seen] > 0.5).sum() > 100 and ((fraction[seen] > 0.05) & (fraction[seen] < 0.5)).sum() > 50
    ratio = luminance(shadowed.views[0])[seen] / luminance(unshadowed.views[0])[seen]
    assert np.percentile(np.abs(ratio - (1 - fraction[seen])), 99) < 0.03
    assert (fraction[shadowed.masks[0]] == 0).all()  # off the painting and behind the occluders
    assert np.array_equal(shadowed.outputs["shadow_free"], unshadowed.views)  # the scene without shadows, exactly
    free = luminance(shadowed.outputs["shadow_free"][0])[seen]
    assert np.percentile(np.abs(luminance(shadowed.views[0])[seen] / free - (1 - fraction[seen])), 99) < 0.03


def test_no_occluder_no_shadow_and_no_draw():
    out, timings = render([], [spot(-1.0, 0.0, 0.5)])
    assert out.outputs["shadow_masks"].shape == (1, *SMALL) and not out.outputs["shadow_masks"].any()
    assert np.array_equal(out.outputs["shadow_free"], out.views)
    assert "shadow_mask" not in timings and "shadow_free" not in timings


@pytest.mark.parametrize("preset", ["shadows_only", "misaligned"])
def test_the_dataset_hands_them_out_only_when_asked_and_the_rest_is_unchanged(preset):
    # View effects on (exposure, noise): the shadow-free view gets the same draws.
    config = small_config(preset, n_views=2, n_occluders=(2, 3), exposure_jitter=True, sensor_noise=True)
    plain = SidarDataset(None, config, seed=1).sample(0)
    both = SidarDataset(None, config.replace(shadow_mask_output=True, shadow_free_output=True), seed=1).sample(0)
    assert "shadow_masks" not in plain and "shadow_free" not in plain
    assert both["shadow_masks"].shape == (2, 1, *SMALL) and both["shadow_masks"].dtype == torch.float32
    assert both["shadow_free"].shape == (2, 3, *SMALL) and both["shadow_free"].dtype == torch.float32
    assert both["shadow_masks"].max() > 0.2  # several lights: a shadow blocks a part of the light
    for key in plain:
        assert torch.equal(torch.as_tensor(plain[key]), torch.as_tensor(both[key])), key
    # Where no light is blocked on the painting (a 0 in the mask: any blocked light is at least 1/255),
    # the shadow-free view is the view.
    unshadowed = (both["shadow_masks"][:, 0] == 0) & (both["masks"][:, 0] == 0)
    free, views = (both[key].permute(0, 2, 3, 1)[unshadowed] for key in ("shadow_free", "images"))
    assert torch.equal(free, views)
    shadowed = both["shadow_masks"][:, 0] > 0.1
    brighter = both["shadow_free"].mean(1)[shadowed] >= both["images"].mean(1)[shadowed]
    assert shadowed.sum() > 20 and brighter.float().mean() > 0.99


@pytest.mark.parametrize("preset", ["misaligned", "paper_misaligned"])
def test_the_shadow_free_view_is_the_scene_rendered_without_shadows_pixel_for_pixel(preset):
    """Glass, reflections, transmittance maps and antialiasing (paper preset) included. With
    ``mesh_detail: auto`` the meshes may differ, as their level follows the shadows' size too."""
    config = small_config(preset, n_views=3, n_occluders=(2, 4), mesh_detail="fixed")
    dataset = SidarDataset(None, config, seed=0)
    settings = RenderSettings.from_config(config)
    for index in range(2):
        sequence, painting = dataset.scene(index), dataset.source.painting(index, config.image_size)
        with_outputs = shared_renderer(replace(settings, outputs=settings.outputs | {"shadow_free"})).render(sequence, painting)
        without_shadows = shared_renderer(replace(settings, shadows=False)).render(sequence, painting)
        assert np.array_equal(with_outputs.outputs["shadow_free"], without_shadows.views)
        assert not np.array_equal(with_outputs.views, without_shadows.views)  # there were shadows to remove


ELLIPSE_SIZE = (192, 256)
LIGHT_AT, BALL_AT, BALL_RADIUS = np.array([-0.6, 0.3, 2.0]), np.array([0.05, -0.05, 0.35]), 0.12


def one_ball_shadow(alpha):
    """The reference camera's shadow mask ``(H, W)`` in [0, 1] and masks of a grey ball of opacity
    ``alpha`` lit by one spot light, and each pixel's distance, in pixels along the painting, from
    the ball's analytic shadow (the cone of directions from the light that meet the sphere):
    negative inside."""
    camera = Camera(*geometry.reference_camera(ELLIPSE_SIZE, 0.9))
    light = Light("spot", LIGHT_AT[None], np.ones(3), float(LIGHT_AT @ LIGHT_AT), 0.7, 0.8)
    caster = Occluder("sphere", BALL_AT, np.eye(3), np.full(3, BALL_RADIUS),
                      Material(np.array([0.5, 0.5, 0.5, alpha]), 0.0, 1.0, specular=0.0))
    view = ViewScene(camera, (light,), (caster,), LAMBERTIAN, 0.0)
    settings = RenderSettings(ELLIPSE_SIZE, outputs=frozenset({"shadow_masks"}), shadow_map_size=2048)
    painting = np.full((*ELLIPSE_SIZE, 3), 200, np.uint8)
    out = shared_renderer(settings).render(SceneSequence(ELLIPSE_SIZE, (view,)), painting)
    h, w = ELLIPSE_SIZE
    to_plane = np.linalg.inv(camera.K @ np.column_stack([camera.R[:, 0], camera.R[:, 1], camera.t]))
    u, v = np.meshgrid(np.arange(w, dtype=float), np.arange(h, dtype=float))
    p = np.einsum("ij,jyx->yxi", to_plane, np.stack([u, v, np.ones_like(u)]))
    rays = np.concatenate([p[..., :2] / p[..., 2:], np.zeros((h, w, 1))], axis=-1) - LIGHT_AT
    axis = BALL_AT - LIGHT_AT
    angle = np.arccos(np.clip(rays @ axis / (np.linalg.norm(rays, axis=-1) * np.linalg.norm(axis)), -1, 1))
    pixel = np.linalg.norm(geometry.project(camera.K, camera.R, camera.t, np.array([[0, 0, 0.0], [1e-3, 0, 0]]))[1]
                           - geometry.project(camera.K, camera.R, camera.t, np.zeros((1, 3)))[0]) / 1e-3  # px per unit
    distance = (angle - np.arcsin(BALL_RADIUS / np.linalg.norm(axis))) * np.linalg.norm(rays, axis=-1) * pixel
    return out.outputs["shadow_masks"][0] / 255.0, out.masks[0], distance


def test_an_opaque_ball_shadow_matches_its_analytic_ellipse_within_a_pixel():
    mask, hidden, distance = one_ball_shadow(1.0)
    inside, outside = ~hidden & (distance < -1), ~hidden & (distance > 1)
    assert inside.sum() > 300 and (mask[inside] >= 0.5).all() and (mask[outside] < 0.5).all()


def test_a_transparent_ball_shadow_follows_its_opacity():
    medians = []
    for alpha in (0.25, 0.5, 0.75):
        mask, hidden, distance = one_ball_shadow(alpha)
        core = ~hidden & (distance < -3)
        assert 0 < mask[core].min() and mask[core].max() < 1
        medians.append(float(np.median(mask[core])))
    # The opacity, raised a little by the Fresnel reflectance the transmittance map also counts.
    assert all(alpha <= m <= alpha + 0.05 for alpha, m in zip((0.25, 0.5, 0.75), medians)), medians


def test_export_writes_and_reads_both_outputs_back_byte_for_byte(tmp_path):
    config = small_config(image_size=(24, 32), n_views=2, shadow_mask_output=True, shadow_free_output=True)
    dataset = SidarDataset(None, config, seed=3)
    export_dataset(dataset, tmp_path, count=2, progress=False)
    assert {"0-s.png", "0-f.png"} <= {path.name for path in (tmp_path / "000001").iterdir()}
    for index in range(2):
        read, rendered = ExportedDataset(tmp_path)[index], dataset.sample(index)
        for key in ("shadow_masks", "shadow_free"):
            assert torch.equal(read[key], rendered[key]), (index, key)
