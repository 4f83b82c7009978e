"""The renderer, proved by rendering: each pyrender/OSMesa quirk has a test that fails if it returns."""

import ast
import gc
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import torch

import sidar_torch.render
from sidar_torch import SidarDataset, geometry
from sidar_torch.render import RenderSettings, SceneRenderer, shared_renderer
from sidar_torch.scene import Camera, Light, Material, Occluder, SceneSequence, ViewScene, sample_sequence

from conftest import SMALL, WHITE, small_config, textured_painting

pytestmark = pytest.mark.gl  # renders



def one_view(size, occluders=(), lights=(), ambient=1.0, camera=None):
    """A one-view sequence through the reference camera (or ``camera``)."""
    camera = camera or Camera(*geometry.reference_camera(size, 0.9))
    view = ViewScene(camera, tuple(lights), tuple(occluders), WHITE, ambient)
    return SceneSequence(size, (view,))


def overhead_spot(irradiance=2.0, height=2.0):
    position = np.array([0.0, 0.0, height])
    return Light("spot", position[None], np.ones(3), irradiance * height**2, 0.5, 0.6)


def cube(position, half=0.1, material=None):
    return Occluder("cube", np.asarray(position, float), np.eye(3), np.full(3, half),
                    material or Material(np.array([0.8, 0.2, 0.2, 1.0]), 0.0, 1.0))


@pytest.mark.parametrize("size", [SMALL, (131, 257), (40, 320), (77, 33)])
def test_label_is_the_painting_bit_exactly(size):
    # Catches: the half-pixel principal-point offset (a shift blurs every texel), texture row
    # order (flipped image), and GL_UNPACK_ALIGNMENT (odd RGB widths come out sheared).
    painting = textured_painting(size)
    out = shared_renderer(RenderSettings(size)).render(one_view(size), painting)
    assert np.array_equal(out.label, painting)


def test_ambient_only_view_reproduces_the_texture_with_exact_srgb():
    # pyrender's gamma-2.2 output encoding is up to 9 levels off here; the exact sRGB encode is <= 1.
    painting = textured_painting(SMALL, seed=1)
    out = shared_renderer(RenderSettings(SMALL)).render(one_view(SMALL, ambient=1.0), painting)
    assert np.abs(out.views[0].astype(int) - painting).max() <= 1
    assert not out.masks[0].any()


def test_shadows_darken_the_painting_under_an_occluder():
    # Catches the program-validation failure with shadow maps (an exception) and lost shadows.
    settings = RenderSettings(SMALL, occluders_visible=False)
    white = np.full((*SMALL, 3), 200, np.uint8)
    occluder = cube([0.0, 0.0, 0.3], half=0.15)
    seq = one_view(SMALL, occluders=[occluder], lights=[overhead_spot()], ambient=0.05)
    shadowed = shared_renderer(settings).render(seq, white).views[0].astype(float)
    unshadowed = shared_renderer(replace(settings, shadows=False)).render(seq, white).views[0].astype(float)
    h, w = SMALL
    centre = (slice(h // 2 - 5, h // 2 + 5), slice(w // 2 - 5, w // 2 + 5))
    assert shadowed[centre].mean() < 0.5 * unshadowed[centre].mean()
    assert np.abs(shadowed[:8, :8] - unshadowed[:8, :8]).max() <= 1  # far from the shadow: unchanged


def test_transparent_occluder_is_blended_and_masked():
    renderer = shared_renderer(RenderSettings(SMALL))
    white = np.full((*SMALL, 3), 200, np.uint8)
    glass = Material(np.array([0.2, 0.4, 0.9, 0.4]), 0.0, 0.2)
    out = renderer.render(one_view(SMALL, occluders=[cube([0.0, 0.0, 0.3], 0.15, glass)], ambient=1.0), white)
    h, w = SMALL
    pixel = out.views[0][h // 2, w // 2].astype(int)
    assert out.masks[0][h // 2, w // 2]  # the paper's semantics: transparent occluders occlude
    assert 0 < pixel[0] < 200 and pixel[2] > pixel[0]  # blended: neither the occluder's nor the painting's colour


def test_masks_cover_visible_occluders_and_ignore_parts_behind_the_painting():
    renderer = shared_renderer(RenderSettings(SMALL))
    painting = textured_painting(SMALL)
    h, w = SMALL
    above = renderer.render(one_view(SMALL, occluders=[cube([0.0, 0.0, 0.3])]), painting)
    assert above.masks[0][h // 2, w // 2] and not above.masks[0][2, 2]
    # An occluder entirely behind the painting is hidden by it: the mask must stay empty.
    behind = renderer.render(one_view(SMALL, occluders=[cube([0.0, 0.0, -0.3])]), painting)
    assert not behind.masks[0].any()
    invisible = shared_renderer(RenderSettings(SMALL, occluders_visible=False)).render(
        one_view(SMALL, occluders=[cube([0.0, 0.0, 0.3])]), painting)
    assert not invisible.masks[0].any()


def test_background_is_masked():
    size = SMALL
    camera = Camera(geometry.intrinsics_from_fov(120, size), *geometry.look_at(np.array([0.0, 0.0, 0.5])))
    out = shared_renderer(RenderSettings(size)).render(one_view(size, camera=camera), textured_painting(size))
    masks = out.masks[0]
    assert masks[0, 0] and masks[-1, -1] and not masks[size[0] // 2, size[1] // 2]
    assert np.all(out.views[0][masks] == 0)  # black background


def test_shader_programs_are_built_once():
    # pyrender's cache key changes at every call on OSMesa: programs would grow with every render.
    cfg = small_config(n_lights=(3, 4), n_occluders=(1, 3))
    renderer = shared_renderer(RenderSettings.from_config(cfg))
    painting = textured_painting(cfg.image_size)
    for seed in range(10):
        renderer.render(sample_sequence(cfg, np.random.default_rng(seed)), painting)
    count = renderer.program_count
    for seed in range(10):  # the same scenes again: every variant they need is built
        renderer.render(sample_sequence(cfg, np.random.default_rng(seed)), painting)
    # At most 20 variants: lit painting, and lit occluders plain, reflecting and refracting (quirk 8),
    # each with and without shadows and with shadows and transmittance, the painting without shadows
    # once per number of light groups (3 and 4 here, quirk 6); shadow depth; transmittance;
    # segmentation of painting and occluders; unlit label; unlit opacity painting and occluders.
    assert renderer.program_count == count <= 20


def test_rendering_is_deterministic_with_many_lights():
    # pyrender sums lights in set order; address-based hashes made that order (and rounding) vary.
    # Full-size views with several coloured lights: at 96 x 128 too few pixels round differently.
    cfg = small_config(image_size=(384, 512), n_views=2, n_lights=(4, 4), light_types=("spot", "point"),
                       n_occluders=(0, 0))
    renderer = shared_renderer(RenderSettings.from_config(cfg))
    painting = textured_painting(cfg.image_size)
    seq = sample_sequence(cfg, np.random.default_rng(7))
    first = renderer.render(seq, painting)
    for _ in range(4):
        junk = [object() for _ in range(1000)]  # noqa: F841  (moves new nodes to other addresses)
        again = renderer.render(seq, painting)
        assert np.array_equal(first.views, again.views) and np.array_equal(first.masks, again.masks)


@pytest.mark.slow
def test_collecting_one_renderer_does_not_break_another():
    # pyrender's Renderer.__del__ deleted GL objects by id in whatever context was current.
    painting = textured_painting(SMALL)
    seq = one_view(SMALL, occluders=[cube([0.0, 0.0, 0.3])], lights=[overhead_spot()])
    a = SceneRenderer(RenderSettings(SMALL))
    expected = a.render(seq, painting)
    b = SceneRenderer(RenderSettings(SMALL))
    b.render(seq, painting)
    del a
    gc.collect()
    assert np.array_equal(b.render(seq, painting).views, expected.views)
    b.close()
    b.close()
    with pytest.raises(RuntimeError, match="after close"):
        b.render(seq, painting)


def test_wrong_inputs_are_rejected():
    renderer = shared_renderer(RenderSettings(SMALL))
    with pytest.raises(ValueError, match="painting"):
        renderer.render(one_view(SMALL), np.zeros((*SMALL, 3), np.float32))
    with pytest.raises(ValueError, match="image_size"):
        renderer.render(one_view((64, 64)), np.zeros((64, 64, 3), np.uint8))


def test_a_camera_a_thousandth_above_a_wide_painting_still_sees_it():
    # The near plane follows the camera down: at far / 2000 it would clip the painting away.
    cfg = small_config("ambient", image_size=(64, 512), camera_height=(1e-3, 1e-3), n_views=3, max_tilt_deg=30)
    s = SidarDataset(config=cfg, seed=0).sample(0)
    assert float(s["masks"][0].mean()) == 0.0  # the reference view is all painting
    assert float(s["masks"][1:].mean()) < 0.5


def test_bilinear_shadow_filter_sharpens_shadow_edges_only():
    # Coarse shadow maps (about 3 px per texel here) make the filters' footprints visible.
    seq = one_view(SMALL, occluders=[cube((0.05, 0.02, 0.3), half=0.15)], lights=[overhead_spot()], ambient=0.0)
    painting = np.full((*SMALL, 3), 200, np.uint8)
    settings = RenderSettings(SMALL, 128, occluders_visible=False)

    def green(**changes):
        return SceneRenderer(replace(settings, **changes)).render(seq, painting).views[0, ..., 1].astype(int)

    tent, bilinear, lit = green(), green(shadow_filter="bilinear"), green(shadows=False)
    assert tent.min() == 0 and bilinear.min() == 0  # a full shadow under both
    # Where the tent filter leaves the painting fully lit, so does the narrower bilinear one.
    assert np.array_equal(bilinear[tent == lit], lit[tent == lit])
    penumbra = {name: int(((view > 0) & (view < lit)).sum()) for name, view in (("tent", tent), ("bilinear", bilinear))}
    assert 0 < penumbra["bilinear"] < 0.8 * penumbra["tent"], penumbra


def test_config_shadow_filter_reaches_the_dataset_renderer():
    images = {name: SidarDataset(None, small_config("shadows_only", n_views=2, shadow_filter=name, n_occluders=(3, 3)),
                                 seed=0).sample(0)["images"] for name in ("tent", "bilinear")}
    assert not torch.equal(images["tent"], images["bilinear"])


def test_unknown_shadow_filter_is_named():
    with pytest.raises(ValueError, match="shadow_filter"):
        RenderSettings(SMALL, shadow_filter="box")
    with pytest.raises(ValueError, match="shadow_filter"):
        small_config(shadow_filter="box")


@pytest.mark.parametrize("setup, expected", [
    # OSMesa missing: pyrender's OSMesa platform cannot be imported.
    ("import os, sys; os.environ['PYOPENGL_PLATFORM'] = 'osmesa'; sys.modules['pyrender.platforms.osmesa'] = None",
     "apt-get install libosmesa6"),
    ("import os; os.environ['PYOPENGL_PLATFORM'] = 'vulkan'", "expected 'osmesa' or 'egl'"),
])
def test_a_platform_that_cannot_open_says_what_is_missing(setup, expected):
    script = (f"{setup}\nfrom sidar_torch.render import RenderSettings, SceneRenderer\n"
              "SceneRenderer(RenderSettings((8, 8)))\n")
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert result.returncode != 0
    assert "RuntimeError" in result.stderr and expected in result.stderr, result.stderr[-500:]


def test_render_settings_come_from_the_config_and_key_the_shared_renderer():
    config = small_config("shadows_only", mask_min_opacity=0.5, opacity_output=True, shadow_filter="bilinear")
    settings = RenderSettings.from_config(config)
    assert settings == RenderSettings(SMALL, 512, "bilinear", "fitted", 0.25, "trilinear", shadows=True,
                                      occluders_visible=False, mask_min_opacity=0.5, outputs=frozenset({"opacities"}))  # auto maps
    assert shared_renderer(RenderSettings(SMALL)) is shared_renderer(RenderSettings((96, 128), 1024))
    assert shared_renderer(RenderSettings(SMALL)).settings == RenderSettings(SMALL)


@pytest.mark.parametrize("field, value, expected", [
    ("image_size", (96,), "image_size: expected (H, W)"), ("image_size", (0, 5), "image_size"),
    ("image_size", (9.5, 5), "image_size"), ("shadow_map_size", 1000, "shadow_map_size: expected a power of two"),
    ("shadow_map_size", 8, "shadow_map_size"), ("shadow_frustum", "tight", "shadow_frustum"),
    ("texture_filter", "nearest", "texture_filter"), ("mesh_error_px", -1.0, "mesh_error_px"),
    ("mask_min_opacity", 2.0, "mask_min_opacity"), ("footprint_tile", 0, "footprint_tile: expected an integer"),
    ("footprint_tile", 16.0, "footprint_tile"),
])
def test_wrong_render_settings_name_the_field(field, value, expected):
    with pytest.raises(ValueError, match=expected.replace("(", r"\(").replace(")", r"\)")):
        RenderSettings(**{"image_size": SMALL, field: value})
    with pytest.raises(TypeError, match="settings"):
        SceneRenderer(SMALL)


def test_the_render_layer_does_not_import_the_config():
    # Settings reach the renderer as a RenderSettings only (issue 12 item 4).
    paths = sorted(Path(sidar_torch.render.__file__).parent.glob("*.py"))
    assert len(paths) > 5
    for path in paths:
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom):
                modules = [node.module or ""] + [f"{node.module or ''}.{a.name}" for a in node.names]
            elif isinstance(node, ast.Import):
                modules = [a.name for a in node.names]
            else:
                continue
            assert not any("config" in m.split(".") for m in modules), (path.name, modules)


def test_sizes_beyond_the_gl_limits_name_the_field_and_the_limit():
    # Issue 13 item 4: without the check, GL raised "GLError ... glRenderbufferStorage" naming no field.
    renderbuffer, texture = shared_renderer(RenderSettings(SMALL)).gl_limits
    assert renderbuffer >= 1024 and texture >= 1024
    side = min(renderbuffer, texture)
    with pytest.raises(ValueError, match=rf"image_size: \(64, {side + 1}\) .* GL_MAX_\w+_SIZE = {side}"):
        SceneRenderer(RenderSettings((64, side + 1)))
    with pytest.raises(ValueError, match=rf"shadow_map_size: {2 * texture} .* GL_MAX_TEXTURE_SIZE = {texture}"):
        SceneRenderer(RenderSettings(SMALL, 2 * texture))
    # The check itself, with made-up limits (no GL needed).
    with pytest.raises(ValueError, match="image_size: .* GL_MAX_RENDERBUFFER_SIZE = 100: expected H, W <= 100"):
        RenderSettings((96, 128)).check_gl_limits(100, 4096)
    with pytest.raises(ValueError, match="shadow_map_size: 1024 .* = 1000: expected a power of two <= 512"):
        RenderSettings((96, 128)).check_gl_limits(4096, 1000)
    RenderSettings((96, 128), 1024).check_gl_limits(1024, 1024)  # at the limit: fine
