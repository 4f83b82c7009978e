"""Multisample antialiasing of the colour pass (config ``antialias``), proved by rendering: edges get
intermediate values, nothing moves, masks, opacities and the label are unchanged, wrong counts raise."""

import numpy as np
import pytest

from sidar_torch import load_config
from sidar_torch.render import RenderSettings, SceneRenderer
from sidar_torch.scene import Material, Occluder

from conftest import SMALL, render_flat_painting

pytestmark = pytest.mark.gl  # renders

GREY = 200
BLACK = Material(np.array([0.0, 0.0, 0.0, 1.0]), 0.0, 1.0, specular=0.0)


def render(antialias):
    """One unlit view (ambient 1, no lights) of a flat grey painting behind a black sphere: with
    one sample per pixel each painting pixel is either grey or black."""
    sphere = Occluder("sphere", np.array([0.03, -0.02, 0.3]), np.eye(3), np.full(3, 0.15), BLACK)
    return render_flat_painting([sphere], ambient=1.0, painting=GREY, outputs=frozenset({"opacities"}), antialias=antialias)


def test_antialiasing_blends_the_silhouette_and_moves_nothing():
    sharp, smooth = render(1), render(4)
    grey = sharp.views[0][..., 0].astype(int)
    soft = smooth.views[0][..., 0].astype(int)
    inside = ~sharp.background[0]  # the painting's pixels (the sphere lies within it)
    assert set(np.unique(grey[inside])) == {0, GREY}  # one sample: only the two colours
    between = (soft > 0) & (soft < GREY)
    assert between.sum() > 40  # the sphere's outline, about 2 pi r = 100 pixels long, is blended
    # Blended pixels lie on the one-sample silhouette: each has a neighbour of the other colour there.
    edge = np.zeros_like(inside)
    for axis in (0, 1):
        step = np.diff(grey, axis=axis) != 0
        lo = [slice(None)] * 2
        hi = [slice(None)] * 2
        lo[axis], hi[axis] = slice(None, -1), slice(1, None)
        edge[tuple(lo)] |= step
        edge[tuple(hi)] |= step
    assert edge[between].all()
    # Away from the outline nothing changes, and the sphere's area is the same (coverage is unbiased).
    assert np.array_equal(soft[~edge], grey[~edge])
    area_sharp, area_soft = (grey[inside] == 0).sum(), ((GREY - soft[inside]) / GREY).sum()
    assert abs(area_soft - area_sharp) < 0.02 * area_sharp, (area_sharp, area_soft)


def test_masks_opacities_and_label_are_the_same_with_and_without_antialiasing():
    sharp, smooth = render(1), render(4)
    assert sharp.masks[0].any() and not sharp.masks[0].all()
    assert np.array_equal(sharp.masks, smooth.masks)
    assert np.array_equal(sharp.outputs["opacities"], smooth.outputs["opacities"])
    assert np.array_equal(sharp.label, smooth.label)
    assert np.array_equal(sharp.background, smooth.background)
    assert not np.array_equal(sharp.views, smooth.views)


def test_the_config_carries_antialias_into_the_settings():
    assert RenderSettings.from_config(load_config("misaligned", antialias=4)).antialias == 4
    assert RenderSettings.from_config(load_config("misaligned")).antialias == 1


@pytest.mark.parametrize("value", [0, 3, 16, True, 2.5, "4"])
def test_wrong_sample_counts_raise_naming_the_field(value):
    with pytest.raises(ValueError, match="antialias"):
        load_config("misaligned", antialias=value)
    with pytest.raises(ValueError, match="antialias"):
        RenderSettings(SMALL, antialias=value)


def test_a_count_the_context_does_not_offer_raises_naming_the_field():
    from sidar_torch.render.framebuffer import sample_counts

    try:
        renderer = SceneRenderer(RenderSettings(SMALL, antialias=8))
    except ValueError as error:
        assert "antialias" in str(error) and "GL_MAX_SAMPLES" in str(error)
    else:  # a driver that offers 8 samples (llvmpipe offers only 4)
        renderer._platform.make_current()
        assert 8 in sample_counts()
        renderer.close()
