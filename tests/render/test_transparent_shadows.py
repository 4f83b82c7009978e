"""Shadows of transparent occluders (issue 5, item 3): lighter than opaque ones, tinted by the
occluder's colour, and without cost or change in views with no transparent caster.

Scenes: a white painting seen by the reference camera, a sphere above it and white spot lights to
the side, so the sphere's shadow falls beside it on the painting; the umbra of an opaque sphere in
the same place tells where to look.
"""

import numpy as np
import torch
from scipy.ndimage import binary_erosion

from sidar_torch.render import RenderSettings, shared_renderer
from sidar_torch.scene import Light, Material, Occluder
from sidar_torch.sample.effects import srgb_to_linear

from conftest import SMALL
from test_realism import render, sphere
from test_render import cube
import pytest

pytestmark = pytest.mark.gl  # renders

WHITE = 255


def side_spot(x: float, irradiance: float = 1.0) -> Light:
    """A white spot light at ``(x, 0, 2)`` aimed at the painting's centre."""
    position = np.array([x, 0.0, 2.0])
    return Light("spot", position[None], np.ones(3), irradiance * float(position @ position), 0.6, 0.7)


def umbra(lights, ambient=0.0, at=(0.0, 0.0)):
    """Painting pixels an opaque sphere (see :func:`ball`) leaves at most 2 levels
    above the unlit painting (in the shadow of every light in ``lights``), less a 2-pixel border
    (transmittance maps have half the depth map's resolution: their shadows' edges are softer)."""
    opaque, mask = render([ball(1.0, at=at)], lights, ambient=ambient, painting=WHITE)
    unlit, _ = render([], [], ambient=ambient, painting=WHITE)
    return binary_erosion(~mask & (opaque.max(axis=2) <= unlit.max(axis=2) + 2), iterations=2)


def ball(alpha, rgb=(1.0, 1.0, 1.0), at=(0.0, 0.0)):
    """A diffuse sphere of radius 0.12 at height 0.3 above the painting's point ``(x, y) = at``."""
    material = Material(np.array([*rgb, alpha]), 0.0, 1.0, specular=0.0)
    return Occluder("sphere", np.array([*at, 0.3]), np.eye(3), np.full(3, 0.12), material)


def linear(image: np.ndarray) -> np.ndarray:
    return srgb_to_linear(torch.from_numpy(image / 255.0)).numpy()


def test_transparent_shadow_passes_one_minus_alpha_and_alpha_one_is_as_dark_as_opaque():
    light = [side_spot(-1.0)]
    shadow = umbra(light)
    lit, _ = render([], light, painting=WHITE)
    opaque, _ = render([ball(1.0)], light, painting=WHITE)
    clear, _ = render([ball(0.3)], light, painting=WHITE)
    nearly_opaque, _ = render([ball(0.999)], light, painting=WHITE)  # alpha < 1: the transparent path
    assert shadow.sum() > 100 and opaque[shadow].max() == 0
    # Light through clear glass of alpha 0.3 keeps 70 % of its energy, less where the Fresnel
    # reflection grows towards the sphere's rim, once per caster (twice would leave 49 %).
    passed = linear(clear[shadow]) / linear(lit[shadow])
    assert 0.62 < np.median(passed) < 0.70 and np.percentile(passed, 90) < 0.70
    assert np.array_equal(clear[shadow][:, 0], clear[shadow][:, 1])  # clear glass: no tint
    assert nearly_opaque[shadow].max() <= 2  # alpha -> 1 joins the opaque path continuously


def test_red_glass_tints_its_shadow_red_while_an_opaque_shadow_stays_neutral():
    light = [side_spot(-1.0, 1.5)]
    shadow = umbra(light, ambient=0.05)
    red, _ = render([ball(0.3, (0.8, 0.1, 0.1))], light, ambient=0.05, painting=WHITE)
    solid, _ = render([ball(1.0, (0.8, 0.1, 0.1))], light, ambient=0.05, painting=WHITE)
    assert shadow.sum() > 100
    assert np.median(linear(red[shadow][:, 0]) / linear(red[shadow][:, 1])) > 2.5
    assert np.array_equal(solid[shadow][:, 0], solid[shadow][:, 1]) and solid[shadow].min() > 50


def test_each_shadowed_light_reads_its_own_transmittance_map():
    # Two lights from different directions and a sphere off the centre, so that it lies in a
    # different part of each light's map: each light's shadow of red glass is red where only that
    # light is blocked, and what neither light's shadow touches stays neutral.
    lights = [side_spot(-1.0, 0.6), Light("spot", np.array([[0.3, -1.0, 2.0]]), np.ones(3), 0.6 * 5.09, 0.6, 0.7)]
    at = (0.25, 0.2)
    red, _ = render([ball(0.3, (0.8, 0.1, 0.1), at)], lights, painting=WHITE)
    white, _ = render([ball(0.3, at=at)], lights, painting=WHITE)
    shadows = [umbra([light], at=at) for light in lights]
    for mine, other in (shadows, shadows[::-1]):
        only = mine & ~other
        assert only.sum() > 50
        assert np.median(linear(red[only][:, 0]) / linear(red[only][:, 1])) > 1.25
        assert np.array_equal(white[only][:, 0], white[only][:, 1])
    bare, _ = render([], lights, painting=WHITE)
    opaque, mask = render([ball(1.0, at=at)], lights, painting=WHITE)
    untouched = binary_erosion(~mask & np.all(opaque == bare, axis=2), iterations=2)  # softer edges: see umbra
    assert untouched.sum() > 1000 and np.array_equal(red[untouched], bare[untouched])


def test_views_without_transparent_casters_skip_the_maps_and_glass_behind_the_painting_changes_nothing():
    # The transmittance lookup is exactly 1 where no transparent caster lies between a fragment
    # and the light, so the skip changes no pixel: glass under the painting (which lies between it
    # and the light) must leave every pixel as in the same view without it.
    renderer = shared_renderer(RenderSettings(SMALL))  # the renderer of ``render``
    lights = [side_spot(-1.0)]
    solid = cube([0.2, 0.1, 0.25])
    passes = renderer._passes.transmittance.passes
    opaque_only, _ = render([solid], lights, ambient=0.1, painting=WHITE)
    assert renderer._passes.transmittance.passes == passes  # skipped
    glass_below = sphere(Material(np.array([0.8, 0.1, 0.1, 0.3]), 0.0, 1.0), height=-0.3)
    with_glass, _ = render([solid, glass_below], lights, ambient=0.1, painting=WHITE)
    assert renderer._passes.transmittance.passes == passes + 1  # drawn, for the one shadowed light
    assert np.array_equal(with_glass, opaque_only)


def test_a_view_with_only_transparent_casters_keeps_no_stale_opaque_shadow():
    lights = [side_spot(-1.0)]
    first, _ = render([ball(0.3)], lights, painting=WHITE)
    render([cube([0.3, 0.0, 0.3], half=0.2)], lights, painting=WHITE)  # fills the depth map
    again, _ = render([ball(0.3)], lights, painting=WHITE)
    assert np.array_equal(first, again)


def test_transmittance_tiles_grow_by_powers_of_two():
    # The tiles' texture keeps a power-of-two height as it grows: llvmpipe compiles every program that
    # reads it anew for a height of the other kind, which a later sample would pay mid-stream.
    renderer = shared_renderer(RenderSettings(SMALL))  # the renderer of ``render``
    lights = [side_spot(x, 0.5) for x in (-1.0, -0.6, 0.6)]
    render([ball(0.3)], lights, painting=WHITE)
    tiles = renderer._passes.transmittance.tiles
    assert tiles >= 3 and tiles & (tiles - 1) == 0
