"""The scene sampler: pure, reproducible and within the configured ranges."""

import math

import numpy as np
import pytest

from sidar_torch import geometry
from sidar_torch.config import OCCLUDER_SHAPES as SHAPE_NAMES
from sidar_torch.scene import sample_sequence

from conftest import SMALL, small_config


def test_same_rng_state_same_sequence_and_different_seeds_differ():
    cfg = small_config(n_views=4)
    a = sample_sequence(cfg, np.random.default_rng([0, 5]))
    assert a == sample_sequence(cfg, np.random.default_rng([0, 5]))
    assert a != sample_sequence(cfg, np.random.default_rng([0, 6]))


def test_aligned_views_share_the_reference_camera():
    seq = sample_sequence(small_config("aligned", n_views=4), np.random.default_rng(0))
    assert all(v.camera == seq.views[0].camera for v in seq.views)
    assert not all(v.lights == seq.views[0].lights for v in seq.views)  # but not the lights


@pytest.mark.parametrize("preset", ["misaligned", "aligned"])
def test_reference_height_places_view_0_and_leaves_the_other_cameras_to_camera_height(preset):
    heights = {"camera_height": (0.6, 0.7), "reference_height": (1.4, 1.5)}
    for seed in range(10):
        default = sample_sequence(small_config(preset, n_views=4, camera_height=(0.6, 0.7)), np.random.default_rng(seed))
        placed = sample_sequence(small_config(preset, n_views=4, **heights), np.random.default_rng(seed))
        assert 0.6 <= default.views[0].camera.position[2] <= 0.7
        assert 1.4 <= placed.views[0].camera.position[2] <= 1.5
        for view in placed.views[1:]:
            z = view.camera.position[2]
            assert (1.4 <= z <= 1.5) if preset == "aligned" else (0.6 <= z <= 0.7)


def test_cameras_respect_tilt_and_fov_and_see_the_centre():
    cfg = small_config(n_views=6, max_tilt_deg=30, fov_deg=(40, 50))
    for seed in range(30):
        seq = sample_sequence(cfg, np.random.default_rng(seed))
        for view in seq.views[1:]:
            c = view.camera
            axis = c.R[2]  # camera z axis in world coordinates
            tilt = math.degrees(math.acos(-axis[2]))
            assert tilt <= 30 + 1e-9
            fov = math.degrees(2 * math.atan(max(cfg.image_size) / 2 / c.K[0, 0]))
            assert 40 - 1e-9 <= fov <= 50 + 1e-9
            centre = geometry.project(c.K, c.R, c.t, np.zeros((1, 3)))[0]
            np.testing.assert_allclose(centre, [(cfg.image_size[1] - 1) / 2, (cfg.image_size[0] - 1) / 2])


def _tilts(config, sequences=150):
    """Tilts, in degrees, of the cameras of views 1.. of ``sequences`` sampled sequences."""
    return np.array([math.degrees(math.acos(-view.camera.R[2][2]))
                     for seed in range(sequences)
                     for view in sample_sequence(config, np.random.default_rng(seed)).views[1:]])


def test_max_tilt_deg_moves_the_tilt_distribution_or_says_which_fields_to_move():
    wide = small_config(camera_xy=5.0, camera_height=(0.5, 1.0), n_occluders=(0, 0), n_lights=(0, 0))
    highest = {cap: _tilts(wide.replace(max_tilt_deg=cap), 40).max() for cap in (30, 60, 85)}
    assert 25 < highest[30] <= 30 and 55 < highest[60] <= 60 and 80 < highest[85] <= 85
    # The default box tilts at most atan(sqrt(2)) = 54.7 deg: a larger limit would change nothing, so it is
    # refused naming the fields that reach it; the default (90) limits nothing, as the box alone decides.
    with pytest.raises(ValueError, match=r"max_tilt_deg.*54\.74 deg.*raise camera_xy or lower camera_height"):
        small_config(max_tilt_deg=89.9)
    assert 45 < _tilts(small_config(), 60).max() <= math.degrees(math.atan(math.sqrt(2)))


def test_point_and_area_lights_cover_the_whole_painting():
    cfg = small_config(light_types=("point", "area"), n_lights=(3, 3), image_size=(40, 320))
    corners = geometry.plane_corners(cfg.image_size)
    for seed in range(10):
        for view in sample_sequence(cfg, np.random.default_rng(seed)).views:
            for light in view.lights:
                assert light.outer_cone <= 1.0 + 1e-9
                for e in light.emitters:
                    rays = corners - e
                    cos = rays @ (-e / np.linalg.norm(e)) / np.linalg.norm(rays, axis=1)
                    assert np.all(np.arccos(np.clip(cos, -1, 1)) < light.inner_cone)


def test_scene_per_view_false_keeps_one_scene():
    seq = sample_sequence(small_config(scene_per_view=False, n_occluders=(2, 2)), np.random.default_rng(3))
    first = seq.views[0]
    assert all(v.lights == first.lights and v.occluders == first.occluders for v in seq.views)
    seq = sample_sequence(small_config(n_occluders=(2, 2)), np.random.default_rng(3))
    assert any(v.occluders != seq.views[0].occluders for v in seq.views[1:])


def test_no_occluder_encloses_a_camera():
    # Occluders drawn in the cameras' own height band, large: many placements would enclose one.
    from sidar_torch.render.meshes import unit_primitive

    cfg = small_config(n_views=6, n_occluders=(6, 6), occluder_height=(0.7, 1.0), occluder_xy=0.3,
                       occluder_size=(0.1, 0.2), occluder_shapes=("sphere", "cube"))
    placed = 0
    for seed in range(20):
        seq = sample_sequence(cfg, np.random.default_rng(seed))
        centres = np.stack([v.camera.position for v in seq.views])
        for view in seq.views:
            placed += len(view.occluders)
            for occluder in view.occluders:
                mesh = unit_primitive(occluder.shape).copy()
                mesh.apply_transform(occluder.object_to_world())
                # Inside a convex mesh = behind the plane of every face.
                side = np.einsum("fa,cfa->cf", mesh.face_normals, centres[:, None] - mesh.triangles[None, :, 0])
                assert not (side < 0).all(axis=1).any()
    assert placed > 20 * 6 * 6 // 2  # most occluders still find a place


def test_the_kind_tables_of_config_scene_and_renderer_name_the_same_kinds():
    """A kind is a row in each layer's table: config's names (``config.allowed``), the scene's
    sampling rows (``scene.kinds``) and the renderer's meshes (``render.meshes``)."""
    from sidar_torch.config import LIGHT_TYPES, OCCLUDER_MATERIALS, OCCLUDER_SHAPES
    from sidar_torch.config.allowed import LIGHT_EMITTERS
    from sidar_torch.render.meshes import MESHES
    from sidar_torch.scene import LIGHT_KINDS, MATERIAL_KINDS, SHAPES

    assert set(LIGHT_KINDS) == set(LIGHT_TYPES) == set(LIGHT_EMITTERS)
    assert set(MATERIAL_KINDS) == set(OCCLUDER_MATERIALS)
    assert set(SHAPES) == set(MESHES) == set(OCCLUDER_SHAPES)
    assert all(spec.levels or spec.polyhedron for spec in MESHES.values())  # each shape can be built


@pytest.mark.parametrize("name", sorted(SHAPE_NAMES))
def test_a_shapes_bounds_hold_every_mesh_of_it_and_its_radius_every_scaled_vertex(name):
    """``Shape.box``, ``disc`` and ``ball`` hold every vertex of every level and variant (each region
    is convex, so the faces too), and ``Shape.radius`` the scaled vertices, never above ``|scale|``."""
    from sidar_torch.render.meshes import MESHES, unit_primitive
    from sidar_torch.scene import SHAPES, occluder_radius

    shape = SHAPES[name]
    vertices = np.vstack([unit_primitive(name, variant, level).vertices for variant in range(shape.variants)
                          for level in range(max(len(MESHES[name].levels), 1))])
    assert (np.abs(vertices) <= np.array(shape.box) + 1e-12).all()
    assert (np.hypot(vertices[:, 0], vertices[:, 1]) <= shape.disc + 1e-12).all()
    assert (np.linalg.norm(vertices, axis=1) <= shape.ball + 1e-12).all()
    rng = np.random.default_rng(0)
    slack = []
    for scale in rng.uniform(0.01, 0.3, (200, 3)):
        farthest = np.linalg.norm(vertices * scale, axis=1).max()
        radius = shape.radius(scale)
        assert farthest <= radius * (1 + 1e-12) and radius <= np.linalg.norm(scale) * (1 + 1e-12)
        slack.append(radius / farthest)
    assert max(slack) < 1.5  # a bound, not a loose one
    cfg = small_config(occluder_shapes=(name,), n_occluders=(2, 2))
    occluder = sample_sequence(cfg, np.random.default_rng(1)).views[0].occluders[0]
    assert occluder_radius(occluder) == shape.radius(occluder.scale)


@pytest.mark.parametrize("kind", ["spot", "point", "area"])
def test_every_light_kind_is_drawn_with_its_emitters(kind):
    config = small_config(light_types=(kind,), n_lights=(2, 2), area_light_samples=4)
    lights = sample_sequence(config, np.random.default_rng(0)).views[0].lights
    assert [light.kind for light in lights] == [kind, kind]
    assert all(len(light.emitters) == (4 if kind == "area" else 1) for light in lights)
    assert all(0 <= light.inner_cone <= light.outer_cone for light in lights)


def test_blender_spot_falloff_puts_the_inner_cone_at_the_blend_in_cos():
    def spots(**fields):
        cfg = small_config(n_views=6, light_types=("spot",), **fields)
        return [light for view in sample_sequence(cfg, np.random.default_rng(4)).views for light in view.lights]

    pairs = list(zip(spots(), spots(spot_falloff="blender")))  # the same draws: cone and blend u
    assert len(pairs) > 6
    for quadratic, blender in pairs:
        u = 1.0 - quadratic.inner_cone / quadratic.outer_cone
        cos_outer = math.cos(blender.outer_cone)
        assert blender.outer_cone == quadratic.outer_cone and blender.smooth_falloff and not quadratic.smooth_falloff
        assert math.cos(blender.inner_cone) == pytest.approx(cos_outer + (1.0 - cos_outer) * u, abs=1e-12)


def paper_occluders(material, on, views=120):
    cfg = small_config(n_views=views, n_occluders=(3, 3), occluder_materials=(material,), paper_occluder_materials=on)
    return [o.material for view in sample_sequence(cfg, np.random.default_rng(3)).views for o in view.occluders]


def test_paper_occluder_materials_draw_the_papers_colours_and_principled_ranges():
    """Blender's colour input ``np.random.uniform(0, 1, 4)`` is uniform per linear channel; our HSV draw
    (value at least 0.2) is not. The paper's Principled BSDF has roughness U(0, 0.5), coat roughness
    and transmission U(0, 1)."""
    from scipy import stats

    paper, ours = (np.array([m.base_color[:3] for m in paper_occluders("metallic", on)]) for on in (True, False))
    assert min(stats.kstest(paper[:, c], "uniform").pvalue for c in range(3)) > 0.01
    assert max(stats.kstest(ours[:, c], "uniform").pvalue for c in range(3)) < 0.01
    metals = paper_occluders("metallic", True)
    assert max(m.roughness for m in metals) <= 0.5 and min(m.roughness for m in metals) < 0.05
    principled = paper_occluders("principled", True)
    for name, top in (("roughness", 0.5), ("coat_roughness", 1.0), ("transmission", 1.0), ("metallic", 1.0)):
        values = np.array([getattr(m, name) for m in principled])
        assert values.max() <= top and values.max() > 0.9 * top and values.min() < 0.1 * top, name


def test_paper_glass_and_transparent_filter_the_painting_by_the_papers_colour_squared():
    """The paper's Glass and Transparent BSDFs take a colour uniform per linear channel and filter the
    light at both of a body's surfaces: the painting behind is seen through its square. Transparent
    ones have no shading of their own (alpha 0) and take the refraction path, undeviated."""
    from scipy import stats

    from sidar_torch.render.mirror import REFRACTION, mirror_define

    for kind in ("glass", "transparent"):
        tints = np.array([m.base_color[:3] for m in paper_occluders(kind, True)])
        assert min(stats.kstest(np.sqrt(tints[:, c]), "uniform").pvalue for c in range(3)) > 0.01, kind
    clear = paper_occluders("transparent", True)
    assert all(m.base_color[3] == 0.0 and m.specular == 0.0 and 1.0 < m.ior < 1.001 for m in clear)
    assert all(mirror_define(m) == REFRACTION for m in clear)
    blended = paper_occluders("transparent", False)
    assert all(0.2 <= m.base_color[3] <= 0.7 and m.ior == 1.0 and mirror_define(m) is None for m in blended)


@pytest.mark.parametrize("kind, field", [("point", "light_intensity"), ("spot", "spot_intensity"), ("area", "area_intensity")])
def test_a_drawn_intensity_dims_far_lights_and_leaves_every_other_draw(kind, field):
    """The paper's generator draws a light's power, so its intensity is the drawn one wherever it is (the
    painting's centre gets ``I cos / d**2``); by default the irradiance there is drawn whatever the distance."""
    def lights(**fields):
        cfg = small_config(n_views=8, light_types=(kind,), area_light_samples=1, **fields)
        return [light for view in sample_sequence(cfg, np.random.default_rng(5)).views for light in view.lights]

    by_irradiance, by_intensity = lights(), lights(**{field: (2.0, 2.0)})
    assert len(by_irradiance) > 10
    for a, b in zip(by_irradiance, by_intensity):  # the same positions, colours and cones: one draw either way
        assert np.array_equal(a.emitters, b.emitters) and np.array_equal(a.color, b.color)
        assert (a.inner_cone, a.outer_cone) == (b.inner_cone, b.outer_cone)
    assert np.allclose([light.intensity for light in by_intensity], 2.0)
    assert np.ptp([light.intensity for light in by_irradiance]) > 0.5  # the irradiance draw: far lights made strong


def test_focal_uniform_draws_the_focal_length_not_the_angle():
    """The paper's lens is uniform in 15-30 mm on a 36 mm sensor: its angle is not uniform in 61.9-100.4 deg."""
    from scipy import stats

    def focals(**fields):
        cfg = small_config(n_views=40, fov_deg=(61.9, 100.4), **fields)
        views = [v for seed in range(10) for v in sample_sequence(cfg, np.random.default_rng(seed)).views[1:]]
        return np.array([v.camera.K[0, 0] / (SMALL[1] / 2) for v in views])  # 1 / tan(fov / 2)

    shortest, longest = 1 / math.tan(math.radians(100.4) / 2), 1 / math.tan(math.radians(61.9) / 2)
    paper, angle = focals(focal_uniform=True), focals()
    assert paper.min() >= shortest - 1e-9 and paper.max() <= longest + 1e-9
    assert stats.kstest((paper - shortest) / (longest - shortest), "uniform").pvalue > 0.01
    assert stats.kstest((angle - shortest) / (longest - shortest), "uniform").pvalue < 0.01


def test_paper_rotation_draws_blenders_euler_angles_not_a_uniform_rotation():
    """The paper's ``rotation=(rx, ry, rz)``, each uniform in [0, 2 pi), turns an occluder's axis to
    ``Rz Ry Rx e_z``, whose height ``cos rx cos ry`` is not uniform in [-1, 1] as a uniform rotation's is."""
    from scipy import stats

    def axis_heights(**fields):
        cfg = small_config(n_views=60, n_occluders=(3, 3), **fields)
        return np.array([o.rotation[2, 2] for seed in range(3)
                         for v in sample_sequence(cfg, np.random.default_rng(seed)).views for o in v.occluders])

    paper, uniform = axis_heights(paper_rotation=True), axis_heights()
    assert len(paper) > 300
    products = np.cos(np.random.default_rng(0).uniform(0, 2 * np.pi, (2, 20000))).prod(axis=0)
    assert stats.ks_2samp(paper, products).pvalue > 0.01
    assert stats.kstest(paper, "uniform", args=(-1, 2)).pvalue < 0.01
    assert stats.kstest(uniform, "uniform", args=(-1, 2)).pvalue > 0.01
