"""Realism (issue 5): light kinds and strengths, materials, shapes, mask semantics, presets, exposure.

Each effect is proved by rendering it against a version without it.
"""

import math

import numpy as np
import pytest
import torch

from sidar_torch import SidarDataset, geometry, load_config
from sidar_torch.sample.effects import srgb_to_linear
from sidar_torch.config import OCCLUDER_SHAPES
from benchmarks.exposure import view_exposure
from sidar_torch.render import RenderSettings
from sidar_torch.render.meshes import unit_primitive
from sidar_torch.scene import SHAPES, Camera, Light, Material, Occluder, sample_sequence

from conftest import LAMBERTIAN, SMALL, render_flat_painting, small_config
from test_render import overhead_spot

pytestmark = pytest.mark.gl  # renders

H, W = SMALL
CENTRE = (slice(H // 2 - 6, H // 2 + 6), slice(W // 2 - 6, W // 2 + 6))


def render(occluders=(), lights=(), plane=LAMBERTIAN, ambient=0.0, painting=100, mask_min_opacity=0.0, camera=None,
           occluders_visible=True):
    """One reference-camera view of a flat painting of grey level (or RGB) ``painting``."""
    out = render_flat_painting(occluders, lights, plane, ambient, painting, camera=camera,
                               occluders_visible=occluders_visible, mask_min_opacity=mask_min_opacity)
    return out.views[0].astype(int), out.masks[0]


def sphere(material, radius=0.15, height=0.3, shape="sphere", variant=0):
    return Occluder(shape, np.array([0.0, 0.0, height]), np.eye(3), np.full(3, radius), material, variant)


@pytest.mark.parametrize("shape", OCCLUDER_SHAPES)
def test_every_shape_fits_its_unit_box_renders_and_is_masked(shape):
    for variant in range(SHAPES[shape].variants):
        mesh = unit_primitive(shape, variant)
        assert np.abs(mesh.bounds).max() <= 1 + 1e-9 and mesh.is_watertight
    red = Material(np.array([0.8, 0.1, 0.1, 1.0]), 0.0, 1.0)
    image, mask = render([sphere(red, shape=shape)], ambient=1.0)
    assert mask.sum() > 100 and not mask[:2].any()  # near the centre only (the torus has a hole)
    assert (image[mask, 0] > 2 * image[mask, 1] + 10).mean() > 0.9  # the occluder's red, not the grey painting


@pytest.mark.parametrize("shape", sorted(s for s, facts in SHAPES.items() if facts.variants > 1))
def test_shape_variants_are_drawn_deterministically_and_all_occur(shape):
    cfg = small_config(n_views=6, n_occluders=(3, 3), occluder_shapes=(shape,))
    seq = sample_sequence(cfg, np.random.default_rng(5))
    assert seq == sample_sequence(cfg, np.random.default_rng(5))
    variants = {o.variant for s in range(10) for v in sample_sequence(cfg, np.random.default_rng(s)).views
                for o in v.occluders}
    assert variants == set(range(SHAPES[shape].variants))
    assert not np.array_equal(unit_primitive(shape, 0).vertices[:8], unit_primitive(shape, 1).vertices[:8])
    assert np.array_equal(unit_primitive(shape, 3).vertices, unit_primitive(shape, 3).vertices)


def test_prism_is_an_extruded_star_shaped_polygon():
    for variant in range(SHAPES["prism"].variants):
        prism = unit_primitive("prism", variant)
        assert np.allclose(sorted(set(prism.vertices[:, 2].round(9))), [-1.0, 1.0])  # two caps only
        outline = prism.vertices[prism.vertices[:, 2] > 0, :2]
        radii = np.linalg.norm(outline, axis=1)
        corners = np.unique(outline[radii > 1e-9].round(9), axis=0)
        assert 5 <= len(corners) <= 9 and radii.max() <= 1 + 1e-9 and radii[radii > 1e-9].min() >= 0.4 - 1e-9
        assert np.isclose(prism.volume, 2 * prism.area_faces[prism.face_normals[:, 2] > 0.5].sum())


def test_glossy_occluder_shows_a_highlight_its_diffuse_twin_lacks():
    colour = np.array([0.3, 0.3, 0.6, 1.0])
    light = [overhead_spot(irradiance=1.5)]
    glossy, mask = render([sphere(Material(colour, 0.0, 0.1, specular=1.0))], light)
    diffuse, _ = render([sphere(Material(colour, 0.0, 0.1, specular=0.0))], light)
    assert glossy[mask].max() >= 250 and diffuse[mask].max() < 200


def test_plane_coat_adds_a_highlight_that_moves_with_the_camera():
    coated = Material(np.ones(4), 0.0, 1.0, specular=0.0, coat=1.0, coat_roughness=0.05)
    light = [overhead_spot(irradiance=1.0)]
    plain, _ = render(lights=light)
    shiny, _ = render(lights=light, plane=coated)
    assert plain.max() < 150 and shiny.max() >= 250
    side = Camera(geometry.intrinsics_from_fov(80, SMALL), *geometry.look_at(np.array([0.3, 0.0, 0.9])))
    moved, _ = render(lights=light, plane=coated, camera=side)
    peak = [np.unravel_index(np.argmax(im.sum(axis=2)), SMALL) for im in (shiny, moved)]
    assert abs(peak[0][1] - peak[1][1]) > 5  # the reflection of the light follows the view


def test_plane_diffuse_switch_and_plane_ranges():
    seq = sample_sequence(small_config(plane_diffuse=True), np.random.default_rng(0))
    assert all(v.plane_material == LAMBERTIAN for v in seq.views)
    cfg = small_config(n_views=6, plane_coat=(0.2, 0.4), plane_specular=(0.6, 0.7))
    materials = [v.plane_material for v in sample_sequence(cfg, np.random.default_rng(0)).views]
    assert all(0.2 <= m.coat <= 0.4 and 0.6 <= m.specular <= 0.7 for m in materials)
    assert len({m.coat for m in materials}) == 6  # a new painting material for every view


def shadow_darkening(occluder, light):
    """``(H, W)`` fraction of the painting's linear light the occluder's shadow takes away (0 lit,
    1 umbra), the occluder itself hidden from the camera."""
    lit, shadowed = (render(occluders, [light], painting=200, occluders_visible=False)[0]
                     for occluders in ([], [occluder]))
    return 1 - srgb_to_linear(torch.from_numpy(shadowed / 255)).mean(2) / srgb_to_linear(torch.from_numpy(lit / 255)).mean(2)


def test_area_lights_give_wider_penumbrae_than_spot_lights():
    height, irradiance = 1.2, 1.5
    centre = np.array([[0.0, 0.0, height]])
    spot = Light("spot", centre, np.ones(3), irradiance * height**2, 0.6, 0.7)
    grid = np.linspace(-0.2, 0.2, 3)  # a 0.4-wide square of 3 x 3 emitters around the spot's position
    emitters = centre + np.array([[x, y, 0.0] for x in grid for y in grid])
    area = Light("area", emitters, np.ones(3), irradiance * height**2 / len(emitters), 0.6, 0.7)
    ball = sphere(Material(np.array([0.5, 0.5, 0.5, 1.0]), 0.0, 1.0), radius=0.12, height=0.35)
    widths, counts = {}, {}
    for light in (spot, area):
        darkening = shadow_darkening(ball, light).numpy()
        assert darkening[H // 2, W // 2] > 0.9  # umbra under the ball for both
        penumbra = (darkening > 0.1) & (darkening < 0.9)
        widths[light.kind] = penumbra[H // 2, W // 2:].sum()  # 10 %-90 % edge width along a radius, pixels
        counts[light.kind] = penumbra.sum()
    # Similar triangles: an emitter square of side 0.4 at 1.2, an edge at 0.35 -> about 0.16 painting
    # units (15 pixels) of penumbra; the spot's edge is the shadow map's filtered texel, about 1 pixel.
    assert widths["spot"] <= 3 and widths["area"] >= 10
    assert counts["area"] > 10 * counts["spot"]


def test_over_exposed_colours_go_to_white():
    # Without the spill a saturated red stays (255, 0, 0) however strong the light.
    image, _ = render(lights=[overhead_spot(irradiance=30.0)], painting=(255, 0, 0))
    assert image[CENTRE].min() >= 240
    dim, _ = render(lights=[overhead_spot(irradiance=1.0)], painting=(255, 0, 0))
    assert dim[CENTRE][..., 1:].max() <= 5  # light that fits stays its colour


def test_glass_highlight_survives_blending_and_its_rim_is_more_opaque():
    light = [overhead_spot(irradiance=1.0)]
    clear = np.array([1.0, 1.0, 1.0, 0.08])
    glass, mask = render([sphere(Material(clear, 0.0, 0.05, 0.5, coat=1.0, coat_roughness=0.15))], light)
    plain, _ = render(lights=light)
    assert mask[H // 2, W // 2]
    assert glass[mask].max() >= 250 > plain.max() + 100  # a highlight at full strength through alpha 0.08
    # Dark glass over a lit painting: the grazing rim (Fresnel) hides the painting more than the middle.
    dark = Material(np.array([0.0, 0.0, 0.0, 0.3]), 0.0, 1.0, specular=0.0)
    image, mask = render([sphere(dark, radius=0.2)], ambient=1.0, painting=200)
    rows = np.flatnonzero(mask[:, W // 2])
    rim, middle = image[rows[1], W // 2].mean(), image[H // 2, W // 2].mean()
    assert rim < middle - 10


def test_mask_min_opacity_leaves_transparent_occluders_out_of_the_mask():
    tinted = Material(np.array([0.2, 0.4, 0.9, 0.4]), 0.0, 0.5)
    opaque = Material(np.array([0.2, 0.4, 0.9, 1.0]), 0.0, 0.5)
    _, paper = render([sphere(tinted)], ambient=1.0)
    image, seen_through = render([sphere(tinted)], ambient=1.0, mask_min_opacity=0.5)
    _, solid = render([sphere(opaque)], ambient=1.0, mask_min_opacity=0.5)
    assert paper[H // 2, W // 2] and solid[H // 2, W // 2]
    assert not seen_through.any()
    assert image[H // 2, W // 2, 2] > image[H // 2, W // 2, 0] + 20  # still drawn, tinted, in the view
    assert RenderSettings.from_config(small_config(mask_min_opacity=0.25)).mask_min_opacity == 0.25


@pytest.mark.parametrize("kind, field", [("point", "light_irradiance"), ("spot", "spot_irradiance"),
                                         ("area", "area_irradiance")])
def test_each_light_kind_gives_its_own_irradiance_at_the_centre(kind, field):
    cfg = small_config(light_types=(kind,), n_lights=(2, 2), **{field: (0.7, 0.7)})
    for view in sample_sequence(cfg, np.random.default_rng(1)).views:
        for light in view.lights:
            e = light.emitters
            d = np.linalg.norm(e, axis=1)
            # An area light's emitters are spread over its square, each a little off its centre.
            tolerance = 0.05 if kind == "area" else 1e-9
            assert math.isclose(float((light.intensity * (e[:, 2] / d) / d**2).sum()), 0.7, rel_tol=tolerance)


@pytest.mark.parametrize("preset", ["paper_misaligned", "paper_aligned"])
def test_paper_presets_load_and_render(preset):
    cfg = load_config(preset)
    assert cfg.occluder_shapes == ("sphere", "cube", "cylinder", "cone", "torus")
    assert cfg.aligned == (preset == "paper_aligned") and cfg.mask_min_opacity == 0.0
    sample = SidarDataset(config=small_config(preset), seed=0).sample(0)
    assert sample["images"].shape == (3, 3, *SMALL) and float(sample["images"].std()) > 0
    if cfg.aligned:
        assert np.allclose(sample["homographies"].numpy(), np.eye(3), atol=1e-5)


@pytest.mark.parametrize("field, value", [
    ("mask_min_opacity", 1.5), ("spot_irradiance", (2.0, 1.0)), ("area_irradiance", (-1.0, 1.0)),
    ("plane_specular", (0.0, 2.0)), ("plane_coat", (0.5, 0.2)), ("plane_coat_roughness", (0.0, 1.5)),
    ("plane_diffuse", "yes"), ("occluder_materials", ("wood",)), ("occluder_shapes", ("teapot",)),
    ("plane_transmission", (0.0, 1.5)), ("plane_transmission", (0.6, 0.2)), ("paper_torus", "yes"),
    ("glass_shadows_opaque", 1), ("area_spread_deg", (0.5, 90.0)), ("area_spread_deg", (90.0, 200.0)),
])
def test_bad_realism_values_raise_naming_the_field(field, value):
    with pytest.raises(ValueError, match=field):
        load_config("misaligned", **{field: value})


def test_view_exposure_counts_painting_pixels_only():
    views = np.zeros((2, 4, 4, 3), np.uint8)
    views[0, 0] = 255  # a row of white
    views[0, 1] = 3  # a row of near-black
    views[0, 2:] = 128
    masks = np.zeros((2, 4, 4), bool)
    masks[0, :, 3] = True  # one column of background, ignored
    masks[1] = True  # a view with no painting
    e = view_exposure(views, masks, bins=4)
    assert e.white[0] == e.black[0] == 0.25 and e.median[0] == 128 and e.painting.tolist() == [12, 0]
    assert np.isclose(e.histogram[0].sum(), 1) and np.isnan(e.white[1])
    with pytest.raises(ValueError, match="masks"):
        view_exposure(views, masks[:1])
    with pytest.raises(ValueError, match="views"):
        view_exposure(views.astype(float), masks)
