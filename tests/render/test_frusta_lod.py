"""Fitted shadow-map frusta, occluder mesh levels of detail and the painting's texture filter,
proved by rendering: smaller maps come closer to a large one, no shadow is lost or clipped, no
acne appears; coarser meshes stay within their stated silhouette error; the chosen level grows
with on-screen size."""

import math
from dataclasses import replace

import numpy as np
import pytest

from sidar_torch import SidarDataset, geometry, load_config
from sidar_torch.render import RenderSettings, SceneRenderer, passes, visibility
from sidar_torch.render.draws import ViewDraws
from sidar_torch.render.meshes import FIXED_LEVEL, detail_level, level_gap, mesh_level, unit_primitive
from sidar_torch.scene import Camera, Light, Material, Occluder, SceneSequence, ViewScene

from conftest import SMALL, WHITE, sample_digest, small_config, textured_painting

pytestmark = pytest.mark.gl  # renders

SIZE = (96, 128)
GREY = np.full((*SIZE, 3), 180, np.uint8)


def occluder(shape, position, half, colour=(0.8, 0.3, 0.2)):
    return Occluder(shape, np.asarray(position, float), np.eye(3), np.full(3, half),
                    Material(np.array([*colour, 1.0]), 0.0, 1.0))


def wide_spot(position=(1.0, 0.2, 1.6), outer=0.95):
    """A spot aimed at the centre whose cone is much wider than the painting: pyrender's frustum
    then spends most of the map outside it."""
    position = np.asarray(position, float)
    intensity = 2.0 * float(position @ position) / (position[2] / np.linalg.norm(position))
    return Light("spot", position[None], np.ones(3), intensity, outer, outer)


def shadow_scene(camera=None):
    """One view: a sphere, a cube and a torus between a wide spot and the painting, plus a cube
    near the light (its shadow is large, it must not be cut by the near plane) and one off to the
    side, outside the camera's view, whose shadow reaches into it."""
    camera = camera or Camera(*geometry.reference_camera(SIZE, 0.9))
    occluders = (occluder("sphere", (-0.2, 0.1, 0.3), 0.09), occluder("cube", (0.3, -0.15, 0.2), 0.06),
                 occluder("torus", (0.05, -0.2, 0.45), 0.1), occluder("cube", (0.8, 0.16, 1.28), 0.03),
                 occluder("sphere", (0.45, 0.0, 0.6), 0.07))
    view = ViewScene(camera, (wide_spot(),), occluders, WHITE, 0.05)
    return SceneSequence(SIZE, (view,))


def render(sequence, smap, frustum, painting=GREY, **settings):
    """``sequence`` rendered by a new renderer with shadow maps of ``smap`` texels fitted by ``frustum``
    (and other ``RenderSettings`` fields)."""
    renderer = SceneRenderer(RenderSettings(sequence.image_size, smap, shadow_frustum=frustum, **settings))
    try:
        return renderer.render(sequence, painting)
    finally:
        renderer.close()


def mse(a, b):
    return float(((a.astype(float) - b.astype(float)) ** 2).mean())


def shadowed(sequence, smap, frustum, visible=True):
    """Pixels the shadows darken: ``(V, H, W)`` bool, lit render minus the render without shadows."""
    lit = render(sequence, smap, frustum, occluders_visible=visible).views.astype(int)
    unshadowed = render(sequence, smap, frustum, occluders_visible=visible, shadows=False).views.astype(int)
    return (unshadowed - lit).max(axis=-1) > 8


def edge(mask):
    """Pixels of ``mask (H, W)`` or its complement that touch the other (4-neighbours)."""
    padded = np.pad(mask, 1, mode="edge")
    neighbours = [padded[:-2, 1:-1], padded[2:, 1:-1], padded[1:-1, :-2], padded[1:-1, 2:]]
    return np.any([n != mask for n in neighbours], axis=0)


def test_off_view_caster_shadows_the_view_and_the_scene_has_shadows():
    """The scene the frustum tests use has shadows, one of them cast by an occluder outside the
    camera's view (a fitted frustum must still hold it)."""
    sequence = shadow_scene()
    cam = sequence.views[0].camera
    off_view = sequence.views[0].occluders[-1]
    assert not visibility.ball_may_be_seen(cam.K, cam.R, cam.t, SIZE, off_view.position, 0.07 * math.sqrt(3))
    without = SceneSequence(SIZE, (ViewScene(cam, sequence.views[0].lights, sequence.views[0].occluders[:-1],
                                             WHITE, 0.05),))
    assert shadowed(sequence, 1024, "cone").sum() > shadowed(without, 1024, "cone").sum() + 50


@pytest.mark.parametrize("visible", [True, False])
def test_fitted_small_map_is_closer_to_the_large_map_than_the_cone(visible):
    sequence = shadow_scene()
    reference = render(sequence, 4096, "fitted", occluders_visible=visible).views
    old_reference = render(sequence, 4096, "cone", occluders_visible=visible).views
    cone = render(sequence, 256, "cone", occluders_visible=visible).views
    fitted = render(sequence, 256, "fitted", occluders_visible=visible).views
    assert mse(fitted, reference) < 0.5 * mse(cone, reference), (mse(fitted, reference), mse(cone, reference))
    assert mse(fitted, old_reference) < 0.5 * mse(cone, old_reference)


@pytest.mark.parametrize("visible", [True, False])
def test_no_shadow_is_lost_or_clipped(visible):
    """At 4096 the shadowed pixels are the same with either frustum, up to the shadows' edge pixels."""
    sequence = shadow_scene()
    cone, fitted = shadowed(sequence, 4096, "cone", visible)[0], shadowed(sequence, 4096, "fitted", visible)[0]
    assert cone.sum() > 300
    differ = cone != fitted
    assert not (differ & ~edge(cone)).any(), int((differ & ~edge(cone)).sum())


def test_no_acne_on_occluders_and_a_tight_near_plane_would_give_it(monkeypatch):
    """Occluders (which shadow themselves on their far side) at 4096 look the same with either
    frustum up to 1 % of their pixels, and at smaller maps the fitted frustum strays from that
    less than the cone's (the cone's coarser texels give stripes on the cube at 256). A near
    plane at the nearest caster, as tight as the far one, shrinks the shader's depth bias about
    50x and the curved occluders shadow themselves in stripes: that is why the fitted projection
    keeps pyrender's near plane."""
    sequence = shadow_scene()
    reference = render(sequence, 4096, "cone")
    on_occluders = reference.masks[0]  # the painting fills the view: the mask is the occluders
    assert on_occluders.sum() > 500

    def differing(smap, frustum):
        views = render(sequence, smap, frustum).views.astype(int)
        return int(((np.abs(views - reference.views).max(axis=-1) > 8)[0] & on_occluders).sum())

    assert differing(4096, "fitted") <= 0.01 * on_occluders.sum()
    for smap in (256, 1024):
        assert differing(smap, "fitted") < differing(smap, "cone")  # 25 < 209 and 3 < 33 here
    # A near plane far beyond every caster: min(near, fitted) is then the fitted one.
    monkeypatch.setattr(passes, "shadow_depth_range", lambda scale: (100.0, 1e3))
    assert differing(1024, "fitted") > 0.05 * on_occluders.sum()  # 222 pixels here, against 3


def test_light_frustum_holds_receivers_within_the_cone_and_casters_beyond_near():
    emitter = np.array([0.4, -0.3, 1.5])
    receivers = geometry.plane_corners(SIZE)
    casters = np.array([[0.0, 0.0, 1.2, 0.05], [0.1, 0.1, 0.3, 0.1]])
    x0, x1, y0, y1, near, far = visibility.light_frustum(emitter, 1.0, receivers, casters)
    R, t = geometry.look_at(emitter)
    cam = receivers @ R.T + t
    tangents = cam[:, :2] / cam[:, 2:]
    assert np.allclose([x0, y0], tangents.min(axis=0)) and np.allclose([x1, y1], tangents.max(axis=0))
    assert far == pytest.approx(cam[:, 2].max())
    assert near == pytest.approx(((casters[:, :3] @ R.T + t)[:, 2] - casters[:, 3]).min())
    assert near < cam[:, 2].min()
    # A narrow cone clips the window to it: nothing outside the cone is lit.
    x0, x1, y0, y1, *_ = visibility.light_frustum(emitter, 0.1, receivers, casters)
    assert max(abs(x0), abs(x1), abs(y0), abs(y1)) == pytest.approx(math.tan(0.1))
    # A margin widens the window; a receiver behind the light has no frustum of this kind.
    wide = visibility.light_frustum(emitter, 1.0, receivers, casters, margin=0.1)
    assert wide[0] < visibility.light_frustum(emitter, 1.0, receivers, casters)[0]
    assert visibility.light_frustum(emitter, 1.0, np.vstack([receivers, [[0.8, -0.6, 3.0]]]), casters) is None


def test_shared_lights_get_one_frustum_over_the_views():
    """With the same lights and occluders in every view (``scene_per_view`` false), a light's
    fitted frustum is the same in every view: one map could serve the sequence."""
    config = small_config("misaligned", scene_per_view=False, n_views=4, n_occluders=(2, 3), n_lights=(2, 2))
    sequence = SidarDataset(None, config, seed=3).scene(0)
    renderer = SceneRenderer(replace(RenderSettings.from_config(config), shadow_map_size=256))
    try:
        frusta = []
        for view in sequence.views:
            draws = ViewDraws(np.eye(4), np.eye(4), np.zeros(3, np.float32), None)
            order = [(a, b) for a, light in enumerate(view.lights) for b in range(len(light.emitters))]
            lights = renderer._shadows.add_lights(draws, view, order, len(order))
            frusta.append(sorted(map(tuple, renderer._shadows.frusta(lights, view, sequence).values())))
        assert frusta[0] and all(f == frusta[0] for f in frusta)
    finally:
        renderer.close()


def sphere_view(radius, distance=0.6):
    """The reference camera over the painting and a sphere of ``radius`` straight below it, no
    lights: the mask is the sphere's silhouette."""
    camera = Camera(*geometry.reference_camera(SIZE, 1.0))
    sphere = occluder("sphere", (0.05, -0.03, 1.0 - distance), radius)
    return SceneSequence(SIZE, (ViewScene(camera, (), (sphere,), WHITE, 1.0),))


@pytest.mark.parametrize("radius", [0.02, 0.08, 0.3])
def test_sphere_silhouette_within_the_stated_error_of_the_finest_mesh(radius):
    """The mask from the level chosen for 0.25 px differs from the finest mesh's only in a thin band
    along the outline: at most ``0.25 px x perimeter + 4`` pixels. A much coarser level breaks
    that bound for the large sphere, so the check can fail."""
    sequence = sphere_view(radius)
    finest = render(sequence, 64, "cone", mesh_error_px=0.0, shadows=False).masks[0]
    chosen = render(sequence, 64, "cone", mesh_error_px=0.25, shadows=False).masks[0]
    perimeter = 2 * math.sqrt(math.pi * finest.sum())
    bound = 0.25 * perimeter + 4
    assert (chosen != finest).sum() <= bound, ((chosen != finest).sum(), bound)
    if radius == 0.3:
        coarse = render(sequence, 64, "cone", mesh_error_px=100.0, shadows=False).masks[0]  # the coarsest level
        assert (coarse != finest).sum() > bound


def test_level_grows_with_on_screen_size():
    settings = RenderSettings(SIZE, 64, mesh_error_px=0.25, shadows=False)
    levels = []
    for radius in (0.005, 0.02, 0.05, 0.1, 0.3):
        sequence = sphere_view(radius)
        levels.append(mesh_level(sequence.views[0].occluders[0], sequence.views[0], settings))
    assert levels == sorted(levels) and levels[0] < levels[-1], levels
    assert [detail_level("sphere", ppu, 0.25) for ppu in (1, 10, 50, 200, 1e4)] == [0, 1, 2, 3, 3]
    assert detail_level("cube", 1e4, 0.25) == 0 and level_gap("cube", 0) == 0.0


def test_shadow_sets_the_level_of_an_invisible_occluder():
    """An occluder cameras cannot see still needs detail for its shadow."""
    sequence = shadow_scene()
    view = sequence.views[0]
    settings = RenderSettings(SIZE, 64, mesh_error_px=0.25, occluders_visible=False)
    assert mesh_level(view.occluders[0], view, settings) > 0
    assert mesh_level(view.occluders[0], view, replace(settings, shadows=False)) == 0


def test_shadow_radii_of_many_lights_are_each_lights_own():
    """Batched over lights, each light's shadow radius is the one it has alone, bit for bit (a mesh
    level must not depend on the other lights), and a light not above the ball gets inf."""
    view = shadow_scene().views[0]
    cam, occ = view.camera, view.occluders[0]
    rng = np.random.default_rng(0)
    emitters = np.vstack([rng.uniform([-1, -1, 0.5], [1, 1, 3], (7, 3)), [[*occ.position[:2], occ.position[2] + 0.05]]])
    radii = visibility.ball_shadow_pixel_radii(cam.K, cam.R, cam.t, emitters, occ.position, 0.1)
    alone = [visibility.ball_shadow_pixel_radii(cam.K, cam.R, cam.t, e, occ.position, 0.1)[0] for e in emitters]
    assert radii.shape == (8,) and radii.tolist() == alone
    assert np.isfinite(radii[:7]).all() and radii[7] == math.inf  # the last light sits inside the ball's cube


@pytest.mark.parametrize("shape", ["sphere", "cylinder", "cone", "torus", "capsule"])
def test_levels_get_finer_and_the_fixed_level_is_the_old_mesh(shape):
    gaps = [level_gap(shape, k) for k in range(4)]
    faces = [len(unit_primitive(shape, 0, k).faces) for k in range(4)]
    assert gaps == sorted(gaps, reverse=True) and faces == sorted(faces)
    old = {"sphere": 1280, "cylinder": 192, "cone": 96, "torus": 2304, "capsule": 1024}
    assert faces[FIXED_LEVEL] == old[shape]
    assert np.abs(unit_primitive(shape, 0, 3).vertices).max() <= 1.0 + 1e-9


def test_bilinear_filter_aliases_where_the_painting_is_shrunk():
    """A camera far away shrinks the painting: trilinear (mipmapped) and bilinear filtering differ
    there; the label (texels at their own size) is the same."""
    painting = textured_painting(SIZE, seed=2)
    camera = Camera(*geometry.reference_camera(SIZE, 1.0))
    shrink = np.array([[0.3, 0, 0.7 * camera.K[0, 2]], [0, 0.3, 0.7 * camera.K[1, 2]], [0, 0, 1.0]])
    far = Camera(shrink @ camera.K, camera.R, camera.t)  # the painting at 30 % in the middle
    sequence = SceneSequence(SIZE, (ViewScene(camera, (), (), WHITE, 1.0), ViewScene(far, (), (), WHITE, 1.0)))
    tri = render(sequence, 64, "cone", painting, texture_filter="trilinear", shadows=False)
    bi = render(sequence, 64, "cone", painting, texture_filter="bilinear", shadows=False)
    assert np.array_equal(tri.label, bi.label) and np.array_equal(tri.views[0], bi.views[0])
    assert mse(tri.views[1], bi.views[1]) > 100


def test_same_seed_same_sample_with_every_knob():
    config = small_config(shadow_frustum="fitted", mesh_detail="auto", mesh_error_px=0.5, texture_filter="bilinear",
                          shadow_map_size=256)
    assert RenderSettings.from_config(config) == RenderSettings(SMALL, 256, "bilinear", "fitted", 0.5, "bilinear")
    assert RenderSettings.from_config(replace(config, mesh_detail="fixed")).mesh_error_px is None
    assert sample_digest(SidarDataset(None, config, seed=5).sample(1)) == \
        sample_digest(SidarDataset(None, config, seed=5).sample(1))


@pytest.mark.parametrize("field, value", [("shadow_frustum", "tight"), ("mesh_detail", "high"),
                                          ("mesh_error_px", -0.1), ("texture_filter", "nearest")])
def test_bad_knobs_name_the_field(field, value):
    with pytest.raises(ValueError, match=field):
        load_config("misaligned", **{field: value})
    if field != "mesh_detail":
        with pytest.raises(ValueError, match=field):
            RenderSettings(SIZE, 64, **{field: value})
