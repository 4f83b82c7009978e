"""A render size apart from the output size (``render.canvas``), proved by rendering: a canvas is the
view's own pixel grid shifted, an overscan holds the view, a crop is part of it, a grown framebuffer
changes no byte, and the lens draws each view once over the canvas its resampling reads."""

import dataclasses

import numpy as np
import pytest

from sidar_torch import SidarDataset, load_config
from sidar_torch.render import RenderSettings, SceneRenderer
from sidar_torch.render.canvas import Canvas
from sidar_torch.choices.lenses import LENS_MODELS, scaled_lens
from sidar_torch.render.resample import MODEL_DEFINES, LensResampling
from sidar_torch.sample.lens_views import SOURCE_SLACK, distortion_maps, lens_canvas
from sidar_torch.scene import sample_sequence

from conftest import small_config, textured_painting

pytestmark = pytest.mark.gl  # renders

OUTPUTS = dict(opacity_output=True, shadow_mask_output=True, shadow_free_output=True)


def scene(config, index=0):
    rng = np.random.default_rng([5, index])
    return sample_sequence(config, rng), textured_painting(config.image_size, index)


def renderer_of(config):
    return SceneRenderer(RenderSettings.from_config(config))


def arrays(rendered):
    """Every per-view array of a ``RenderedSequence``, by name."""
    return {"views": rendered.views, "masks": rendered.masks, "background": rendered.background, **rendered.outputs}


def assert_same(a, b):
    assert a.keys() == b.keys()
    for name in a:
        assert np.array_equal(a[name], b[name]), name


def test_the_image_canvas_and_a_grown_framebuffer_change_no_byte():
    """A canvas of the image's own size at origin 0 is no canvas; after a render into a larger canvas
    (the framebuffer's storage grown), the views, masks, outputs and label are those of a fresh renderer."""
    config = small_config(**OUTPUTS, n_occluders=(2, 3))
    sequence, painting = scene(config)
    fresh = renderer_of(config).render(sequence, painting)
    renderer = renderer_of(config)
    n = len(sequence.views)
    wide = Canvas((config.image_size[0] + 40, config.image_size[1] + 56), np.full((n, 2), -20))
    renderer.render(sequence, painting, canvas=wide)
    assert renderer._passes.target.capacity == (config.image_size[1] + 56, config.image_size[0] + 40)
    for canvas in (None, Canvas(config.image_size, np.zeros((n, 2), int))):
        again = renderer.render(sequence, painting, canvas=canvas)
        assert_same(arrays(again), arrays(fresh))
        assert np.array_equal(again.label, fresh.label)


def test_an_overscan_holds_the_view_and_a_crop_is_part_of_it():
    """Without occluders (so no shadow map is fitted to what a camera sees) a canvas's pixels are the
    view's pixels shifted by its (even) origin: an overscan's window at ``-origin`` is the view, a crop
    is the view's window at ``origin``, up to the projection's rounding: under 0.5 % of the painting's
    pixels, by at most 3 levels. An odd origin regroups the rasteriser's quads (``render.canvas``)."""
    config = small_config(n_occluders=(0, 0))
    sequence, painting = scene(config, 1)
    renderer = renderer_of(config)
    plain = renderer.render(sequence, painting)
    h, w = config.image_size
    n = len(sequence.views)
    origins = np.array([[-14, -8], [-6, -12], [0, -2]])[:n]
    over = renderer.render(sequence, painting, canvas=Canvas((h + 20, w + 30), origins))
    crop_origins = np.array([[10, 6], [2, 20], [32, 0]])[:n]
    crop = renderer.render(sequence, painting, canvas=Canvas((h // 2, w // 2), crop_origins))
    assert over.views.shape == (n, h + 20, w + 30, 3) and crop.masks.shape == (n, h // 2, w // 2)
    assert np.array_equal(over.label, plain.label) and np.array_equal(crop.label, plain.label)
    for i, ((ox, oy), (cx, cy)) in enumerate(zip(origins, crop_origins)):
        windows = ((over, slice(-oy, -oy + h), slice(-ox, -ox + w), slice(0, h), slice(0, w)),
                   (crop, slice(0, h // 2), slice(0, w // 2), slice(cy, cy + h // 2), slice(cx, cx + w // 2)))
        for drawn, rows, cols, view_rows, view_cols in windows:
            masks = drawn.masks[i][rows, cols], plain.masks[i][view_rows, view_cols]
            assert (masks[0] != masks[1]).mean() < 0.002
            inside = ~masks[0] & ~masks[1]
            diff = np.abs(drawn.views[i][rows, cols].astype(int) - plain.views[i][view_rows, view_cols].astype(int))
            assert diff[inside].max() <= 3 and (diff[inside] > 0).mean() < 0.005
    # Beyond the view the overscan sees more of the painting where the view's edge cuts it.
    assert (~over.masks).sum() >= (~plain.masks).sum()
    # Windows of their own: each view's pixels in its first rows and columns, nothing beyond.
    sizes = np.array([[h + 20, w + 30], [h + 10, w + 20], [h, w]])[:n]
    own = renderer.render(sequence, painting, canvas=Canvas((h + 20, w + 30), origins, sizes))
    assert own.views.shape == over.views.shape
    for i, (wh, ww) in enumerate(sizes):
        masks = own.masks[i][:wh, :ww], over.masks[i][:wh, :ww]
        assert (masks[0] != masks[1]).mean() < 0.002
        inside = ~masks[0] & ~masks[1]
        diff = np.abs(own.views[i][:wh, :ww].astype(int) - over.views[i][:wh, :ww].astype(int))
        assert diff[inside].max(initial=0) <= 3 and (diff[inside] > 0).mean() < 0.005
        beyond = np.ones(own.masks[i].shape, bool)
        beyond[:wh, :ww] = False
        assert own.masks[i][beyond].all() and own.background[i][beyond].all() and not own.views[i][beyond].any()


def test_a_canvas_is_checked_and_named():
    config = small_config()
    sequence, painting = scene(config)
    renderer = renderer_of(config)
    n = len(sequence.views)
    with pytest.raises(ValueError, match="canvas origins: expected one per view"):
        renderer.render(sequence, painting, canvas=Canvas(config.image_size, np.zeros((n + 1, 2), int)))
    limit = renderer.gl_limits[0]
    with pytest.raises(ValueError, match=f"canvas size: .* exceeds this OpenGL context's GL_MAX_RENDERBUFFER_SIZE = {limit}"):
        renderer.render(sequence, painting, canvas=Canvas((16, limit + 1), np.zeros((n, 2), int)))
    with pytest.raises(TypeError, match="canvas: expected a render.Canvas"):
        renderer.render(sequence, painting, canvas=(16, 16))
    with pytest.raises(ValueError, match="canvas size: expected"):
        Canvas((0, 16), np.zeros((n, 2), int))
    with pytest.raises(ValueError, match="canvas origins: expected"):
        Canvas((16, 16), np.zeros((n, 2)))
    with pytest.raises(ValueError, match="boxes: expected"):
        Canvas.covering(np.array([[5, 0, 4, 10]]))
    covering = Canvas.covering(np.array([[-3, 1, 130, 97], [0, -6, 127, 95]]))
    assert covering.origins.tolist() == [[-4, 0], [0, -6]] and covering.size == (102, 135)
    assert covering.sizes.tolist() == [[98, 135], [102, 128]] and covering.window(1) == (102, 128)
    with pytest.raises(ValueError, match="canvas sizes: expected"):
        Canvas((16, 16), np.zeros((n, 2), int), np.full((n, 2), 17))


@pytest.mark.parametrize("model", ["brown_conrady", "division"])
def test_the_lens_canvas_holds_every_pixel_the_resampling_reads(model):
    """The float32 sources the renderer's resampling pass reads (drawn by its own shader) are the exact maps
    within SOURCE_SLACK (default ranges, the strongest barrels that do not fold, a pincushion); each view's
    canvas, from the border's sources, holds the floor and ceiling of every one (up to SOURCE_SLACK); a lens
    of zeros draws the views themselves; the lens path renders once."""
    config = load_config("misaligned", image_size=(48, 64), n_views=3, lens_model=model)
    dataset = SidarDataset(None, config, seed=2)
    renderer = renderer_of(config)
    corners = {"brown_conrady": [(-0.1, 0.03, 0.01, 0.01, 0.0), (-0.14, 0.0, 0.0, 0.0, 0.0), (0.05, 0.03, 0.002, -0.002, 0.0)],
               "division": [(-0.5, 0.0, 0.0, 0.0, 0.0), (0.05, 0.0, 0.0, 0.0, 0.0)]}[model]
    for index, corner in enumerate([None, None, *corners]):
        sequence = dataset.scene(index)
        K = sequence.cameras()[0]
        if corner is not None:
            lenses = np.stack([scaled_lens(model, np.array(corner), k, config.image_size) for k in K])
            sequence = dataclasses.replace(sequence, lenses=lenses)
        lens = LensResampling.of(sequence)
        sources = renderer.lens_sources(lens)
        assert sources.dtype == np.float32 and sources.shape == (3, *config.image_size, 2)
        assert np.abs(sources - distortion_maps(model, lens.lenses, K, config.image_size)).max() < SOURCE_SLACK
        assert (lens.steps > 0).all() == (model == "brown_conrady")
        canvas = lens_canvas(lens.border)
        shifted = sources - canvas.origins[:, None, None, :]
        assert np.floor(shifted.min() + SOURCE_SLACK) >= 0
        assert (np.ceil(shifted.max(axis=(1, 2)) - SOURCE_SLACK) <= canvas.sizes[:, ::-1] - 1).all()
    zero = dataclasses.replace(sequence, lenses=np.zeros((3, 5)))
    identity = LensResampling.of(zero)
    canvas = lens_canvas(identity.border)
    assert canvas.size == config.image_size and not canvas.origins.any()
    assert np.abs(renderer.lens_sources(identity) - distortion_maps("none", None, K, config.image_size)).max() < 1e-4
    dataset.sample(0)  # the renderer warms up at the first sample (SidarDataset.renderer)
    renders = dataset.renderer().renders
    dataset.sample(1)
    assert dataset.renderer().renders == renders + 1


def test_a_lens_that_folds_its_view_or_a_lens_without_a_canvas_is_refused_by_name():
    """Tangential terms can fold a barrel that the config's radial check lets through: Newton's method
    from the shader's start then never settles, and the resampling says so rather than bend garbage."""
    config = load_config("misaligned", image_size=(48, 64), n_views=3, lens_model="brown_conrady")
    sequence, painting = scene(config)
    K = sequence.cameras()[0]
    folding = np.stack([scaled_lens("brown_conrady", np.array([-0.14, 0.0, 0.01, 0.01, 0.0]), k, config.image_size)
                        for k in K])
    with pytest.raises(ValueError, match="lenses: brown_conrady .* still move their sources after 16 Newton steps"):
        LensResampling.of(dataclasses.replace(sequence, lenses=folding))
    with pytest.raises(ValueError, match="sequence.lens_model: expected one of"):
        LensResampling.of(dataclasses.replace(sequence, lens_model="none", lenses=None))
    lens = LensResampling.of(sequence)
    with pytest.raises(ValueError, match="lens: expected a render.canvas.Canvas and one lens per view"):
        renderer_of(config).render(sequence, painting, lens=lens)
    assert set(MODEL_DEFINES) == set(LENS_MODELS)
