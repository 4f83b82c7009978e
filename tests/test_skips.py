"""Work the renderer skips because it cannot change a pixel: each skip rendered on and off.

The skips (``sidar_torch.render.plan``): shadow passes and lookups of emitters that shade
nothing the camera sees, and occluders no camera and no shadow can see.
"""

import numpy as np
import pytest

from sidar_torch import geometry
from sidar_torch.render import shared_renderer
from sidar_torch.render.plan import plan_views
from sidar_torch.scene import Camera, Light, Material, Occluder, SceneSequence, ViewScene, sample_sequence

from conftest import SMALL, small_config, textured_painting

WHITE = Material(np.ones(4), 0.0, 1.0)

NARROW_VIEWS = dict(n_views=4, fov_deg=(20, 30), occluder_xy=1.5, n_occluders=(1, 3))
"""Narrow views of a wide scene: many occluders and their shadows lie outside what a camera sees."""


SWITCHES = ("skip_idle_shadows", "cull_occluders")


@pytest.fixture
def renderer():
    """This process's renderer at ``SMALL`` (shaders already compiled), all skips on, counts at 0."""
    renderer = shared_renderer(SMALL, 1024)
    renderer.skipped.clear()
    yield renderer
    for switch in SWITCHES:
        setattr(renderer, switch, True)


def render_both(renderer, seq, painting, switch):
    """``seq`` rendered with ``renderer.<switch>`` on, then off (and back on)."""
    setattr(renderer, switch, True)
    on = renderer.render(seq, painting)
    setattr(renderer, switch, False)
    off = renderer.render(seq, painting)
    setattr(renderer, switch, True)
    return on, off


def assert_same_pixels(a, b):
    for name in ("views", "masks", "label"):
        x, y = getattr(a, name), getattr(b, name)
        assert np.array_equal(x, y), f"{name}: {int((x != y).sum())} values differ"


@pytest.mark.parametrize("preset", ["shadows_only", "misaligned"])
def test_skipping_shadows_that_cannot_reach_the_view_changes_no_pixel(renderer, preset):
    cfg = small_config(preset, **NARROW_VIEWS)
    painting = textured_painting(SMALL)
    skipped = 0
    for seed in range(6):
        seq = sample_sequence(cfg, np.random.default_rng(seed))
        skipped += sum(len(p.order) - p.n_shadowed for p, v in zip(plan_views(seq, 1024), seq.views) if v.occluders)
        assert_same_pixels(*render_both(renderer, seq, painting, "skip_idle_shadows"))
    assert skipped >= 10  # the skip did happen


@pytest.mark.parametrize("preset", ["shadows_only", "misaligned"])
def test_culling_hidden_occluders_changes_no_pixel(renderer, preset):
    # Transparent and opaque occluders, visible or only casting shadows, in narrow and wide views.
    painting = textured_painting(SMALL)
    for cfg in (small_config(preset, **NARROW_VIEWS), small_config(preset, n_views=4, n_occluders=(2, 3))):
        for seed in range(6):
            seq = sample_sequence(cfg, np.random.default_rng(seed))
            assert_same_pixels(*render_both(renderer, seq, painting, "cull_occluders"))
    assert renderer.skipped["occluders_culled"] >= 10  # counted once per view, in the "on" renders


def overhead_spot(x=0.0):
    position = np.array([x, 0.0, 2.0])
    return Light("spot", position[None], np.ones(3), 8.0, 0.9, 1.0)


def cube(position, half=0.1):
    return Occluder("cube", np.asarray(position, float), np.eye(3), np.full(3, half),
                    Material(np.array([0.8, 0.2, 0.2, 1.0]), 0.0, 1.0))


def test_an_occluder_out_of_view_whose_shadow_misses_is_culled(renderer):
    # Camera over the painting's centre with a narrow view; one cube in view, one far to the side
    # (outside the view, its shadow from the overhead light lands beside it, far from the view),
    # one out of view whose shadow falls on the view's centre.
    size = SMALL
    camera = Camera(geometry.intrinsics_from_fov(30, size), *geometry.look_at(np.array([0.0, 0.0, 1.0])))
    occluders = (cube([0.05, 0.0, 0.4]), cube([1.2, 0.0, 0.3]), cube([0.0, 0.0, 1.5], half=0.05))
    view = ViewScene(camera, (overhead_spot(),), occluders, WHITE, 0.2)
    seq = SceneSequence(size, (view,), True, True)
    (plan,) = plan_views(seq, 1024)
    assert plan.drawn == {0}  # the high cube is above the camera, out of its view
    assert plan.casters == {0, 2}  # the side cube is culled, the high one shadows the view
    on, off = render_both(renderer, seq, textured_painting(size), "cull_occluders")
    assert renderer.skipped["occluders_culled"] == 1
    assert_same_pixels(on, off)
    # The high cube, kept as a caster, does shadow the view: without it the view is brighter.
    without_high = SceneSequence(size, (ViewScene(camera, view.lights, occluders[:2], WHITE, 0.2),), True, True)
    lit = renderer.render(without_high, textured_painting(size))
    assert lit.views.astype(int).sum() > on.views.astype(int).sum()


def test_margins_grow_the_shadow_tests():
    emitter = np.array([[0.0, 0.0, 2.0]])
    region = np.array([[0.3, -0.1], [0.5, -0.1], [0.5, 0.1], [0.3, 0.1]])
    centres, radii = np.array([[0.0, 0.0, 1.0], [0.3, 0.0, 1.0]]), np.array([0.1, 0.1])  # shadows about 0.2 wide
    assert geometry.shadow_may_reach(emitter, centres, radii, region).tolist() == [[False, True]]
    assert geometry.shadow_may_reach(emitter, centres, radii, region[::-1]).tolist() == [[False, True]]
    assert geometry.shadow_may_reach(emitter, centres, radii, region, margins=0.06).tolist() == [[True, True]]
    apart = geometry.shadow_may_fall_on_ball(emitter, centres[:1], radii[:1], centres, radii)
    assert apart.tolist() == [[[True, False]]]  # a ball shadows itself
    near = geometry.shadow_may_fall_on_ball(emitter, centres[:1], radii[:1], centres, radii, margins=0.15)
    assert near.tolist() == [[[True, True]]]
    holding = geometry.shadow_may_fall_on_ball(emitter, np.array([[0.0, 0.0, 1.95]]), np.array([0.1]), centres[1:],
                                               radii[1:])
    assert holding.tolist() == [[[True]]]
