"""The paper's painting and occluders (issue 15, items 2 and 3): the painting's transmission, glass
that casts an opaque shadow, the paper's fixed-size torus and its area lights'
spread.

Transmission and opaque glass shadows are proved by rendering them against a version without them.
"""

import dataclasses
import math

import numpy as np
import pytest

from sidar_torch.render.meshes import unit_primitive
from sidar_torch.render.scene_graph import transmission_factors
from sidar_torch.scene import PAPER_TORUS_SCALE, Light, Material, spread_beam, sample_sequence
from sidar_torch.scene.description import FALLOFFS

from conftest import LAMBERTIAN, SMALL, render_flat_painting, small_config
from test_realism import render
from test_render import overhead_spot
from test_transparent_shadows import WHITE, ball, linear, side_spot, umbra

pytestmark = pytest.mark.gl  # renders


def shader_terms(base, metallic, specular):
    """The lit shader's diffuse colour and normal-incidence reflectance (pyrender's ``c_diff`` and
    ``f0``, with ``programs``' specular level) of a base colour ``base (3,)``."""
    return 0.96 * base * (1 - metallic), 0.08 * specular * (1 - metallic) + metallic * base


@pytest.mark.parametrize("t, m, s", [(0.0, 0.3, 0.5), (0.4, 0.0, 0.7), (0.7, 0.6, 0.2), (0.999, 0.1, 1.0),
                                     (1.0, 0.0, 0.5), (1.0, 0.8, 0.5), (0.5, 1.0, 0.3)])
def test_transmission_factors_scale_the_diffuse_colour_and_keep_the_reflectance(t, m, s):
    texture = np.array([0.9, 0.4, 0.05])  # what the painting's texture multiplies the factor by
    factor, metallic, specular = transmission_factors(Material(np.ones(4), m, 0.5, s, transmission=t))
    assert factor[3] == 1.0 and 0 <= metallic <= 1
    c, f0 = shader_terms(factor[:3] * texture, metallic, specular)
    c_ref, f0_ref = shader_terms(texture, m, s)
    assert np.allclose(c, (1 - t) * c_ref, rtol=0, atol=1e-6) and np.allclose(f0, f0_ref, rtol=0, atol=1e-9)


def test_transmission_darkens_the_diffuse_painting_by_one_minus_t_and_leaves_a_metal_alone():
    light = [overhead_spot(irradiance=1.0)]
    diffuse = Material(np.ones(4), 0.0, 1.0, specular=0.0)
    opaque, _ = render(lights=light, plane=diffuse, painting=200)
    half, _ = render(lights=light, plane=Material(np.ones(4), 0.0, 1.0, specular=0.0, transmission=0.6),
                     painting=200)
    centre = (slice(40, 56), slice(56, 72))
    ratio = linear(half[centre]).mean() / linear(opaque[centre]).mean()
    assert abs(ratio - 0.4) < 0.02, ratio  # 8-bit rounding: within 2 %
    metal = Material(np.ones(4), 1.0, 0.3)
    assert np.array_equal(render(lights=light, plane=metal)[0],
                          render(lights=light, plane=Material(np.ones(4), 1.0, 0.3, transmission=0.6))[0])


def test_plane_transmission_is_drawn_per_view_only_when_its_range_is_not_zero():
    materials = [v.plane_material for v in
                 sample_sequence(small_config(n_views=6, plane_transmission=(0.2, 0.4)), np.random.default_rng(0)).views]
    assert all(0.2 <= m.transmission <= 0.4 for m in materials) and len({m.transmission for m in materials}) == 6
    plain = sample_sequence(small_config(n_views=6), np.random.default_rng(0))
    assert all(v.plane_material.transmission == 0.0 for v in plain.views)


def test_glass_with_an_opaque_shadow_is_as_dark_as_an_opaque_occluder():
    light = [side_spot(-1.0)]
    shadow = umbra(light)
    glass = ball(0.2)
    clear, _ = render([glass], light, painting=WHITE)
    blocking = dataclasses.replace(glass, material=dataclasses.replace(glass.material, opaque_shadow=True))
    dark, _ = render([blocking], light, painting=WHITE)
    assert shadow.sum() > 100
    assert clear[shadow].min() > 100 and dark[shadow].max() == 0  # 80 % of the light passes, or none


def test_glass_shadows_opaque_marks_glass_only():
    def occluder_materials(**overrides):
        cfg = small_config(n_views=6, n_occluders=(3, 3), occluder_materials=("glass", "transparent"), **overrides)
        return [o.material for v in sample_sequence(cfg, np.random.default_rng(1)).views for o in v.occluders]

    for on in (False, True):
        materials = occluder_materials(glass_shadows_opaque=on)
        glass = [m.opaque_shadow for m in materials if m.coat == 1.0]  # glass has a full clear coat
        assert glass and all(g == on for g in glass)
        assert not any(m.opaque_shadow for m in materials if m.coat != 1.0)


def test_paper_torus_has_the_paper_size_and_other_shapes_keep_their_draw():
    torus = unit_primitive("torus")
    assert np.allclose(torus.bounds[1] * PAPER_TORUS_SCALE, np.array([1.25, 1.25, 0.25]) / 7, rtol=1e-3)
    cfg = small_config(n_views=6, n_occluders=(3, 3), occluder_shapes=("torus", "sphere"), paper_torus=True)
    occluders = [o for v in sample_sequence(cfg, np.random.default_rng(2)).views for o in v.occluders]
    tori = [o for o in occluders if o.shape == "torus"]
    spheres = [o for o in occluders if o.shape == "sphere"]
    assert tori and spheres and all(np.array_equal(o.scale, PAPER_TORUS_SCALE) for o in tori)
    low, high = cfg.occluder_size
    assert all(((low <= o.scale) & (o.scale <= high)).all() for o in spheres)


@pytest.mark.parametrize("spread", [10.0, 30.0, 60.0, 90.0])
def test_spread_beam_keeps_the_power_and_cycles_peak(spread):
    inner, outer, irradiance = spread_beam(spread, 1.0)
    assert inner == 0.0 and outer == pytest.approx(math.radians(spread) / 2)
    theta = np.linspace(0.0, outer, 200001)
    falloff = np.cos(theta) * (1 - np.tan(theta) / math.tan(outer))  # the renderer's area_spread profile
    power = 2 * math.pi * np.trapezoid(irradiance * falloff * np.sin(theta), theta)
    assert power == pytest.approx(math.pi, rel=1e-6)  # a unit Lambertian emitter's: pi
    assert irradiance == pytest.approx(math.tan(outer) / (math.tan(outer) - outer))  # Cycles' peak


def test_area_spread_makes_area_lights_beams_and_180_keeps_them_covering():
    cfg = small_config(n_views=6, light_types=("area",), n_lights=(2, 2), area_spread_deg=(20.0, 60.0))
    lights = [light for v in sample_sequence(cfg, np.random.default_rng(3)).views for light in v.lights]
    assert all(light.inner_cone == 0 and math.radians(10) <= light.outer_cone <= math.radians(30) for light in lights)
    covering = [light for v in sample_sequence(small_config(light_types=("area",)), np.random.default_rng(3)).views
                for light in v.lights]
    assert all(light.inner_cone > math.radians(20) for light in covering)  # the painting's corners inside


@pytest.mark.parametrize("falloff", sorted(FALLOFFS))
def test_a_spot_light_fades_between_its_cones_as_its_falloff_says(falloff):
    # A spot light 1 unit straight above a white Lambertian painting, cones of 10 and 25 degrees (0 and 25
    # for an area light's spread): the painting's linear light at each pixel of the middle row, over the
    # centre's, is cos^3 of the angle a from the axis times the falloff, r^2 (pyrender's) or smoothstep(r) =
    # r^2 (3 - 2 r) (Blender's spot blend), r the linear ramp in cos from the outer cone (0) to the inner one
    # (1), or cos a (1 - tan a / tan 25 degrees) (Cycles' spread area light).
    spread = falloff == "area_spread"
    inner, outer = (0.0 if spread else math.radians(10)), math.radians(25)
    light = Light("spot", np.array([[0.0, 0.0, 1.0]]), np.ones(3), 0.5, inner, outer, FALLOFFS[falloff])
    green = linear(render_flat_painting(lights=[light], plane=LAMBERTIAN, painting=255).views[0])[..., 1]
    h, w = SMALL
    row = h // 2
    x, y = (np.arange(w) - (w - 1) / 2) / h, (row - (h - 1) / 2) / h  # world units: the painting is 1 high
    cos = 1.0 / np.sqrt(1.0 + x**2 + y**2)
    r = np.clip((cos - math.cos(outer)) / (math.cos(inner) - math.cos(outer)), 0.0, 1.0)
    tan = np.sqrt(1 - cos**2) / cos
    expected = {"quadratic": r**2, "spot_blend": r**2 * (3 - 2 * r),
                "area_spread": cos * np.clip(1 - tan / math.tan(outer), 0.0, None)}[falloff]
    centre = green[row, w // 2] / cos[w // 2] ** 3 / expected[w // 2]
    assert 0.05 < centre < 0.5 and ((0 < r) & (r < 1)).sum() > 10  # lit, unclipped, the ramp crossed
    np.testing.assert_allclose(green[row], centre * cos**3 * expected, atol=2e-3)


@pytest.mark.parametrize("spill", [True, False])
def test_over_exposed_light_spills_into_white_or_clips_each_channel(spill):
    # A pink light about three times too bright for the red channel of a white painting (its diffuse
    # factor 0.96: red 2.88, green and blue 0.576 in linear light): with the spill the excess whitens
    # every channel; without it each channel clips on its own, as Blender's Standard view transform
    # does, and green and blue keep their own level.
    light = Light("spot", np.array([[0.0, 0.0, 1.0]]), np.array([1.0, 0.2, 0.2]), 3.0 * math.pi, 0.5, 0.6)
    centre = render_flat_painting(lights=[light], plane=LAMBERTIAN, painting=255, highlight_spill=spill).views[0][
        SMALL[0] // 2, SMALL[1] // 2]
    level = linear(centre.astype(np.uint8))
    if spill:
        assert centre.tolist() == [255, 255, 255]
    else:
        assert centre[0] == 255 and abs(level[1] - 0.576) < 0.005 and abs(level[2] - 0.576) < 0.005
