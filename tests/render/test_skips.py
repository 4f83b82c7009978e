"""Work the renderer skips because it cannot change a pixel: each skip rendered on and off.

The skips (``sidar_torch.render.plan``, ``render.footprints`` and ``SceneRenderer._render_view``):
shadow passes and lookups of emitters that shade nothing the camera sees, lookups on the parts of
the painting no caster can shadow, occluders no camera and no shadow can see, the mask draw of a
view with no occluder in sight, and shadow maps drawn again for the same lights and casters.
"""

from dataclasses import replace

import numpy as np
import pytest

from sidar_torch import geometry
from sidar_torch.render import RenderSettings, shared_renderer, visibility
from sidar_torch.render.plan import plan_views
from sidar_torch.scene import Camera, Light, Material, Occluder, SceneSequence, ViewScene, sample_sequence

from conftest import SMALL, WHITE, small_config, textured_painting

pytestmark = pytest.mark.gl  # renders


NARROW_VIEWS = dict(n_views=4, fov_deg=(20, 30), occluder_xy=1.5, n_occluders=(1, 3))
"""Narrow views of a wide scene: many occluders and their shadows lie outside what a camera sees."""


def render_both(settings, seq, painting, switch):
    """``seq`` rendered with ``settings`` (``switch`` on), then with the skip ``switch`` off, each in
    this process's renderer for those settings."""
    on = shared_renderer(settings).render(seq, painting)
    off = shared_renderer(replace(settings, **{switch: False})).render(seq, painting)
    return on, off


def skipped(settings, key):
    """How many times the renderer of ``settings`` has skipped ``key`` so far."""
    return shared_renderer(settings).skipped[key]


def assert_same_pixels(a, b):
    """Two rendered sequences have the same views, masks, label and shadow-free views (if any)."""
    assert a.outputs.keys() == b.outputs.keys()
    for name, x, y in [(n, getattr(a, n), getattr(b, n)) for n in ("views", "masks", "label")] + \
            [(n, a.outputs[n], b.outputs[n]) for n in a.outputs if n == "shadow_free"]:
        assert np.array_equal(x, y), f"{name}: {int((x != y).sum())} values differ"


SOFT = 0.04
"""A light radius whose penumbrae span several pixels in these scenes (soft shadows' wider reads)."""


@pytest.mark.parametrize("preset, light_radius", [("shadows_only", 0.0), ("misaligned", 0.0), ("misaligned", SOFT)])
def test_skipping_shadows_that_cannot_reach_the_view_changes_no_pixel(preset, light_radius):
    cfg = small_config(preset, light_radius=light_radius, **NARROW_VIEWS)
    settings = RenderSettings.from_config(cfg)
    painting = textured_painting(SMALL)
    idle = 0
    for seed in range(6):
        seq = sample_sequence(cfg, np.random.default_rng(seed))
        idle += sum(len(p.order) - p.n_shadowed for p, v in zip(plan_views(seq, settings), seq.views) if v.occluders)
        assert_same_pixels(*render_both(settings, seq, painting, "skip_idle_shadows"))
    assert idle >= 10  # the skip did happen


def test_lights_are_summed_in_rank_order_so_the_shadowed_ones_come_first():
    """The shader's light order is the draw list's, shadowed emitters first: were it another (pyrender's
    set of nodes iterated ranks 5..8 as 8, 5, 6, 7), a shadowed emitter would land past ``n_shadowed`` and
    lose its shadow (a view with 3 occluders and 4 emitters did: 6 pixels lit that the unskipped render
    shadows)."""
    cfg = small_config(image_size=(48, 64), n_occluders=(3, 4), n_lights=(1, 3), light_types=("spot", "point"))
    seq = sample_sequence(cfg, np.random.default_rng(11))
    assert_same_pixels(*render_both(RenderSettings.from_config(cfg), seq, textured_painting((48, 64)),
                                    "skip_idle_shadows"))


@pytest.mark.parametrize("preset", ["misaligned", "paper_misaligned", "shadows_only"])
def test_lookups_only_where_a_caster_can_shadow_the_painting_change_no_pixel(preset):
    """The painting's lit draw split into screen rectangles with only the lookups each needs
    (``render.footprints``) gives the same bytes as one draw with every lookup, with tent and
    bilinear filters, soft shadows (whose lookups read farther), transparent casters (transmittance
    lookups) and antialiasing (paper preset). So does the shadow-free view, drawn in the same pass
    (each part with its lookups, all of its light unshadowed). Parts without a lookup are drawn by
    the program without lookups (one light loop instead of three)."""
    cfg = small_config(preset, image_size=(160, 224), n_views=3, n_occluders=(2, 4), shadow_free_output=True)
    painting = textured_painting((160, 224))
    left_out = softened = lookup_free = 0
    lookups = [dict(shadow_filter="tent"), dict(shadow_filter="bilinear"), dict(light_radius=SOFT)] * 2
    for seed, lookup in zip(range(6), lookups):
        settings = RenderSettings.from_config(cfg.replace(**lookup))
        seq = sample_sequence(cfg, np.random.default_rng(seed))
        for plan in plan_views(seq, settings):
            left_out += sum(part.width * part.height * (plan.n_shadowed - part.end + part.begin)
                            for part in plan.painting_parts)
            lookup_free += sum(part.width * part.height for part in plan.painting_parts if part.begin == part.end)
        split, whole = render_both(settings, seq, painting, "split_shadow_lookups")
        assert_same_pixels(split, whole)
        if settings.light_radius:
            hard = shared_renderer(replace(settings, light_radius=0.0)).render(seq, painting)
            softened += int((hard.views != split.views).any(axis=-1).sum())
    assert left_out > 0  # lookups were left out
    assert softened > 100  # and the soft shadows differ from hard ones
    assert lookup_free > 0
    # Only the parts without a lookup draw with a program that has no spot-light shadows yet outputs
    # the shadow-free view (views without a shadowed light output one colour).
    programs = shared_renderer(settings).program_variants
    assert any("SHADOW_FREE" in defines and "SPOT_LIGHT_SHADOWS" not in defines for defines in programs)


def test_views_under_the_split_threshold_draw_the_painting_whole(monkeypatch):
    """Under ``plan.SPLIT_MIN_PIXELS`` a view's painting is drawn whole (no parts); with the threshold
    lowered, the same 48x64 views are split, for the same bytes."""
    from sidar_torch.render import plan as plan_module
    size = (48, 64)
    assert size[0] * size[1] < plan_module.SPLIT_MIN_PIXELS
    cfg = small_config("misaligned", image_size=size, n_views=3, n_occluders=(2, 4))
    painting = textured_painting(size)
    settings = RenderSettings.from_config(cfg)
    seqs = [sample_sequence(cfg, np.random.default_rng(seed)) for seed in range(4)]
    assert all(not plan.painting_parts for seq in seqs for plan in plan_views(seq, settings))
    whole = [shared_renderer(settings).render(seq, painting) for seq in seqs]
    monkeypatch.setattr(plan_module, "SPLIT_MIN_PIXELS", 1)
    assert any(plan.painting_parts for seq in seqs for plan in plan_views(seq, settings))
    for seq, drawn in zip(seqs, whole):
        assert_same_pixels(shared_renderer(settings).render(seq, painting), drawn)


def test_any_footprint_tile_gives_the_same_pixels():
    """Tiles of 7 pixels (not a divisor of the image's sides) and of 64 split the painting's draw
    otherwise than the default 16, into more or fewer parts, for the same bytes."""
    cfg = small_config("misaligned", image_size=(160, 224), n_views=3, n_occluders=(2, 4))
    painting = textured_painting((160, 224))
    base = RenderSettings.from_config(cfg)
    for seed in range(3):
        seq = sample_sequence(cfg, np.random.default_rng(seed))
        outputs = {}
        for tile in (16, 7, 64):
            settings = replace(base, footprint_tile=tile)
            parts = sum(len(plan.painting_parts) for plan in plan_views(seq, settings))
            outputs[tile] = parts, shared_renderer(settings).render(seq, painting)
        assert outputs[7][0] > outputs[16][0] > outputs[64][0] > 0  # the tiles split the draws otherwise
        for tile in (7, 64):
            assert_same_pixels(outputs[tile][1], outputs[16][1])


@pytest.mark.parametrize("preset, light_radius", [("shadows_only", 0.0), ("misaligned", 0.0), ("shadows_only", SOFT)])
def test_culling_hidden_occluders_changes_no_pixel(preset, light_radius):
    # Transparent and opaque occluders, visible or only casting shadows, in narrow and wide views.
    # Masks drawn, not taken from the outline: culling leaves the mask draws without occluders.
    settings = replace(RenderSettings.from_config(small_config(preset, light_radius=light_radius)),
                       masks_from_outline=False)
    before = skipped(settings, "occluders_culled")
    painting = textured_painting(SMALL)
    for cfg in (small_config(preset, light_radius=light_radius, **NARROW_VIEWS),
                small_config(preset, light_radius=light_radius, n_views=4, n_occluders=(2, 3))):
        assert RenderSettings.from_config(cfg) == replace(settings, masks_from_outline=True)
        for seed in range(6):
            seq = sample_sequence(cfg, np.random.default_rng(seed))
            assert_same_pixels(*render_both(settings, seq, painting, "cull_occluders"))
    assert skipped(settings, "occluders_culled") - before >= 10  # counted once per view, in the "on" renders


@pytest.mark.parametrize("preset", ["misaligned", "paper_misaligned"])
def test_clearing_only_the_texels_a_map_had_written_changes_no_pixel(preset):
    """Shadow and transmittance maps cleared only where their previous draw may have written
    (``render.shadow_array``) give the same bytes as maps cleared whole, sequence after sequence
    (each renderer's maps keep what earlier sequences drew), with transparent casters and shared
    scenes; and far fewer texels are cleared."""
    cfg = small_config(preset, n_views=3, n_occluders=(1, 4))
    settings = RenderSettings.from_config(cfg)
    painting = textured_painting(SMALL)
    gl = {flag: shared_renderer(replace(settings, clear_written_texels=flag))._passes for flag in (True, False)}

    def counts(flag):  # so far: transmittance tiles drawn, depth and transmittance texels cleared
        return np.array([gl[flag].transmittance.passes, gl[flag].shadow_maps.cleared_texels,
                         gl[flag].transmittance.cleared_texels])

    render_both(settings, sample_sequence(cfg, np.random.default_rng(100)), painting, "clear_written_texels")  # maps made
    before = {flag: counts(flag) for flag in gl}
    # Eight sequences: paper_misaligned's first transmittance tiles (new, so cleared whole) come at
    # seed 2, and the later seeds clear what those tiles held (5 seeds passed only when an earlier
    # test of the process had made the tiles).
    for seed in range(8):
        seq = sample_sequence(cfg.replace(scene_per_view=seed % 2 == 0), np.random.default_rng(seed))
        assert_same_pixels(*render_both(settings, seq, painting, "clear_written_texels"))
    (tiles, depth, tints), (tiles_off, depth_off, tints_off) = (counts(flag) - before[flag] for flag in gl)
    assert tiles == tiles_off > 0  # transparent casters were drawn
    assert depth < depth_off / 2 and tints < tints_off / 2  # new layers and tiles count whole


def overhead_spot(x=0.0):
    position = np.array([x, 0.0, 2.0])
    return Light("spot", position[None], np.ones(3), 8.0, 0.9, 1.0)


def cube(position, half=0.1):
    return Occluder("cube", np.asarray(position, float), np.eye(3), np.full(3, half),
                    Material(np.array([0.8, 0.2, 0.2, 1.0]), 0.0, 1.0))


def test_an_occluder_out_of_view_whose_shadow_misses_is_culled():
    # Camera over the painting's centre with a narrow view; one cube in view, one far to the side
    # (outside the view, its shadow from the overhead light lands beside it, far from the view),
    # one out of view whose shadow falls on the view's centre.
    size = SMALL
    camera = Camera(geometry.intrinsics_from_fov(30, size), *geometry.look_at(np.array([0.0, 0.0, 1.0])))
    occluders = (cube([0.05, 0.0, 0.4]), cube([1.2, 0.0, 0.3]), cube([0.0, 0.0, 1.5], half=0.05))
    view = ViewScene(camera, (overhead_spot(),), occluders, WHITE, 0.2)
    seq = SceneSequence(size, (view,))
    settings = RenderSettings(size)
    (plan,) = plan_views(seq, settings)
    assert plan.drawn == {0}  # the high cube is above the camera, out of its view
    assert plan.casters == {0, 2}  # the side cube is culled, the high one shadows the view
    before = skipped(settings, "occluders_culled")
    on, off = render_both(settings, seq, textured_painting(size), "cull_occluders")
    assert skipped(settings, "occluders_culled") - before == 1
    assert_same_pixels(on, off)
    # The high cube, kept as a caster, does shadow the view: without it the view is brighter.
    without_high = SceneSequence(size, (ViewScene(camera, view.lights, occluders[:2], WHITE, 0.2),))
    lit = shared_renderer(settings).render(without_high, textured_painting(size))
    assert lit.views.astype(int).sum() > on.views.astype(int).sum()


def edge_distance(camera, size):
    """``(H, W)``: each pixel centre's distance (px) to the nearest line through a painting edge's image."""
    h, w = size
    half_w, half_h = (s / 2 for s in geometry.plane_size(size))
    to_image = camera.K @ np.column_stack([camera.R[:, 0], camera.R[:, 1], camera.t])
    edges = np.array([[1, 0, half_w], [-1, 0, half_w], [0, 1, half_h], [0, -1, half_h]])  # a . (x, y, 1) = 0
    lines = edges @ np.linalg.inv(to_image)  # rows: image lines l . (u, v, 1) = 0
    u, v = np.meshgrid(np.arange(w, dtype=float), np.arange(h, dtype=float))
    values = lines[:, 0, None, None] * u + lines[:, 1, None, None] * v + lines[:, 2, None, None]
    return (np.abs(values) / np.linalg.norm(lines[:, :2], axis=1)[:, None, None]).min(axis=0)


EDGE_TOLERANCE = 1 / 256
"""Distance (px) from an edge within which a pixel centre may fall on either side of it in the GL
draw: llvmpipe snaps window coordinates to 1/256 px (8 sub-pixel bits), which moves an edge by
up to 1/512 px near its vertices, and applies the top-left rule on ties; vertices the camera
clips (near-plane crossings) carry float32 rounding. Measured: 0.0008 px at worst over the
cameras below."""


def random_cameras(rng, size, n):
    """Cameras at any tilt up to grazing (a few degrees above the plane), looking at random
    points of the painting, with fields of view from narrow to very wide."""
    w, h = geometry.plane_size(size)
    cameras = []
    for k in range(n):
        height = rng.uniform(0.05, 1.5)
        tilt = rng.uniform(0, np.radians(88 if k % 2 else 60))
        angle = rng.uniform(0, 2 * np.pi)
        target = np.array([rng.uniform(-w / 2, w / 2), rng.uniform(-h / 2, h / 2), 0.0])
        position = target + height * np.array([np.tan(tilt) * np.cos(angle), np.tan(tilt) * np.sin(angle), 1.0])
        K = geometry.intrinsics_from_fov(rng.uniform(20, 150), size)
        cameras.append(Camera(K, *geometry.look_at(position, target)))
    return cameras


@pytest.mark.parametrize("size", [SMALL, (77, 33)])
def test_mask_from_the_painting_outline_matches_the_rendered_mask(size):
    rng = np.random.default_rng(5)
    renderer = shared_renderer(RenderSettings(size, masks_from_outline=False))
    painting = textured_painting(size)
    cameras = random_cameras(rng, size, 64)
    views = tuple(ViewScene(c, (), (), WHITE, 1.0) for c in cameras)
    rendered = renderer.render(SceneSequence(size, views), painting).masks
    differ, worst, edge_pixels = 0, 0.0, 0
    for camera, mask in zip(cameras, rendered):
        outline = visibility.painting_mask(camera.K, camera.R, camera.t, size)
        distance = edge_distance(camera, size)
        wrong = outline != mask
        differ += int(wrong.sum())
        worst = max(worst, float(distance[wrong].max(initial=0.0)))
        edge_pixels += int((distance < EDGE_TOLERANCE).sum())
    print(f"{differ} pixels differ, farthest {worst:.2g} px from an edge; {edge_pixels} pixels within {EDGE_TOLERANCE}")
    assert worst < EDGE_TOLERANCE
    # The comparison covers edges: most views show both painting and background.
    assert sum(0 < m.mean() < 1 for m in rendered) >= 32
    assert edge_pixels < 0.001 * rendered.size  # the exception is tiny


def test_views_without_occluders_in_sight_take_the_outline_mask():
    cfg = small_config("misaligned", **NARROW_VIEWS)
    settings = RenderSettings.from_config(cfg)
    before = skipped(settings, "masks_from_outline")
    painting = textured_painting(SMALL)
    for seed in range(4):
        seq = sample_sequence(cfg, np.random.default_rng(seed))
        on, off = render_both(settings, seq, painting, "masks_from_outline")
        assert np.array_equal(on.views, off.views)
        for camera, a, b in zip([v.camera for v in seq.views], on.masks, off.masks):
            assert (edge_distance(camera, SMALL)[a != b] < EDGE_TOLERANCE).all()
    assert skipped(settings, "masks_from_outline") - before >= 4


def unmasked_views(seq, settings):
    """How many views of ``seq`` draw an occluder below ``settings.mask_min_opacity`` (whose mask
    therefore takes the mask's own draw, not the colour pass's stencil)."""
    return sum(any(view.occluders[i].material.base_color[3] < settings.mask_min_opacity for i in plan.drawn)
               for view, plan in zip(seq.views, plan_views(seq, settings)))


@pytest.mark.parametrize("preset, overrides", [
    ("misaligned", {}),
    ("occlusions_only", {"occluder_materials": ["transparent", "glass", "diffuse"], "mask_min_opacity": 0.5}),
    ("misaligned", {"opacity_output": True, "shadow_mask_output": True, "shadow_free_output": True}),
])
def test_masks_from_the_colour_pass_stencil_are_the_drawn_masks(preset, overrides):
    cfg = small_config(preset, n_views=4, n_occluders=(2, 4), **overrides)
    settings = RenderSettings.from_config(cfg)
    before = skipped(settings, "masks_from_stencil")
    painting = textured_painting(SMALL)
    unmasked = 0
    for seed in range(5):
        seq = sample_sequence(cfg, np.random.default_rng(seed))
        on, off = render_both(settings, seq, painting, "masks_from_stencil")
        assert_same_pixels(on, off)
        assert np.array_equal(on.background, off.background)
        assert on.outputs.keys() == off.outputs.keys()
        for name in on.outputs:
            assert np.array_equal(on.outputs[name], off.outputs[name]), name
        unmasked += unmasked_views(seq, settings)
    assert skipped(settings, "masks_from_stencil") - before > 0
    assert unmasked > 0 if settings.mask_min_opacity > 0 else unmasked == 0  # those views take the draw


def test_a_stencil_mask_needs_a_single_sampled_pass_and_the_painting():
    from sidar_torch.render.passes import LitPass

    renderer = shared_renderer(RenderSettings(SMALL, antialias=4))
    with pytest.raises(ValueError, match="stencil: needs a single-sampled colour pass; .* 4 samples per pixel"):
        renderer._passes.draw(None, LitPass(painting_parts=(), stencil=True), [])
    with pytest.raises(ValueError, match="stencil: needs painting_parts"):
        LitPass(stencil=True)


def test_shadow_maps_shared_by_the_views_are_drawn_once():
    cfg = small_config("misaligned", n_views=4, scene_per_view=False, n_occluders=(1, 3), n_lights=(2, 3),
                       light_types=("spot", "point", "area"), mesh_detail="fixed")
    # Fixed meshes: with mesh_detail "auto" a caster's mesh level may change from view to view, which
    # (rightly) changes the map's key and redraws it, so the count below would not hold.
    settings = RenderSettings.from_config(cfg)
    renderer = shared_renderer(settings)
    before = renderer.skipped["shadow_maps_reused"]
    painting = textured_painting(SMALL)
    seqs = [sample_sequence(cfg, np.random.default_rng(seed)) for seed in range(5)]
    first = [renderer.render(seq, painting) for seq in seqs]  # maps reused within each sequence
    reused = renderer.skipped["shadow_maps_reused"] - before
    again = renderer.render(seqs[0], painting)  # after other sequences: their maps must not leak in
    fresh = [shared_renderer(replace(settings, reuse_shadow_maps=False)).render(seq, painting) for seq in seqs]
    assert renderer.skipped["shadow_maps_reused"] - before > reused  # the repeated sequence reused its maps
    for a, b in zip(first, fresh):
        assert_same_pixels(a, b)
    assert_same_pixels(again, fresh[0])
    # Each emitter's map was drawn in the first view that shadows it, and reused by the later ones.
    plans = [plan_views(seq, settings) for seq in seqs]
    assert all(len({p.casters for p in ps}) == 1 for ps in plans)
    shadowed = [[set(p.order[:p.n_shadowed]) for p in ps] for ps in plans]
    assert reused == sum(sum(map(len, views)) - len(set().union(*views)) for views in shadowed) > 0


def test_margins_grow_the_shadow_tests():
    emitter = np.array([[0.0, 0.0, 2.0]])
    region = np.array([[0.3, -0.1], [0.5, -0.1], [0.5, 0.1], [0.3, 0.1]])
    centres, radii = np.array([[0.0, 0.0, 1.0], [0.3, 0.0, 1.0]]), np.array([0.1, 0.1])  # shadows about 0.2 wide
    assert visibility.shadow_may_reach(emitter, centres, radii, region).tolist() == [[False, True]]
    assert visibility.shadow_may_reach(emitter, centres, radii, region[::-1]).tolist() == [[False, True]]
    assert visibility.shadow_may_reach(emitter, centres, radii, region, margins=0.06).tolist() == [[True, True]]
    apart = visibility.shadow_may_fall_on_ball(emitter, centres[:1], radii[:1], centres, radii)
    assert apart.tolist() == [[[True, False]]]  # a ball shadows itself
    near = visibility.shadow_may_fall_on_ball(emitter, centres[:1], radii[:1], centres, radii, margins=0.15)
    assert near.tolist() == [[[True, True]]]
    holding = visibility.shadow_may_fall_on_ball(emitter, np.array([[0.0, 0.0, 1.95]]), np.array([0.1]), centres[1:],
                                               radii[1:])
    assert holding.tolist() == [[[True]]]


@pytest.mark.parametrize("preset", ["misaligned", "paper_misaligned", "aligned"])
def test_the_label_from_the_painting_is_the_drawn_label(preset):
    """View 0's reference camera sees texel (u, v) at pixel (u, v)'s centre: the label is the
    painting itself, which the label draw gives byte for byte, at sizes odd and even, with both
    texture filters and random paintings of every level."""
    rng = np.random.default_rng(5)
    for size, texture_filter in [((17, 23), "trilinear"), ((101, 77), "bilinear"), ((192, 256), "trilinear"),
                                 ((511, 513), "bilinear")]:
        cfg = small_config(preset, image_size=size, texture_filter=texture_filter, n_views=2, n_occluders=(0, 1))
        settings = RenderSettings.from_config(cfg)
        seq = sample_sequence(cfg, rng)
        painting = rng.integers(0, 256, (*size, 3), dtype=np.uint8)
        before = skipped(settings, "label_from_painting")
        on, off = render_both(settings, seq, painting, "label_from_painting")
        assert skipped(settings, "label_from_painting") - before == 1
        assert_same_pixels(on, off)
        assert np.array_equal(off.label, painting)  # drawn


def test_a_view_0_off_the_reference_camera_has_its_label_drawn():
    cfg = small_config(n_views=2, n_occluders=(0, 0))
    seq = sample_sequence(cfg, np.random.default_rng(0))
    tilted = SceneSequence(seq.image_size, (seq.views[1], seq.views[0]))  # view 0 from a random camera
    settings = RenderSettings.from_config(cfg)
    before = skipped(settings, "label_from_painting")
    on, off = render_both(settings, tilted, textured_painting(SMALL), "label_from_painting")
    assert skipped(settings, "label_from_painting") == before  # drawn, not copied
    assert_same_pixels(on, off)
    assert not np.array_equal(on.label, textured_painting(SMALL))
