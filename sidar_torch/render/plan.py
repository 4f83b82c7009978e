"""What each view of a sequence must draw: plain geometry on the scene description, no GL.

Per view, :func:`plan_views` decides

* which occluders the camera may see (**drawn**: colour and mask passes),
* which emitters get a shadow map and lookup (**shadowed**, added first, in a fixed order; with
  ``group_emitters`` a light's emitters are shaded together and shadowed all or none),
* which occluders go into the shadow maps (**casters**).

Everything else cannot change a pixel and is left out (each test below is conservative, and
``tests/render/test_skips.py`` renders with and without every skip and compares bit for bit):

* An emitter whose shadow lookups would read only unoccluded texels at every fragment of the
  view returns "lit" there, so its shadow pass and lookup are skipped (it still shades).
* An occluder outside the camera's view draws no fragment in the colour and mask passes. If
  moreover its shadow from every shadowed emitter misses the visible painting and every drawn
  occluder, its texels in the shadow maps are read by no lookup of the view, so it is not drawn
  at all. Occluders shadow each other, so drawn occluders count as shadow receivers; a blended
  (transparent) occluder is drawn and receives like any other; occluders neither drawn nor
  receiving need no shadow.

"Reads" includes the lookup's filter footprint (:data:`SHADOW_READ_TEXELS`), turned into an angle
around the emitter by :func:`shadow_margin`, and with soft shadows the penumbra's search around it
(:func:`soft_reach`): :func:`lookup_margins`.

And within the painting's colour draw, each shadowed emitter's lookup is made only where a caster
may be read (``render.footprints``: the draw is split into screen rectangles, ``painting_parts``),
in views of at least :data:`SPLIT_MIN_PIXELS` pixels: in smaller ones the split's planning and
draws cost more than the lookups it saves, and the painting is drawn whole (the same pixels).

When every view shares the lights and occluders (``scene_per_view`` false) every view gets the
union of the views' casters, so an emitter's shadow map is the same in every view that shadows
it, and is drawn once (``SceneRenderer`` keys each map on what it depends on and keeps it with
the emitter's pooled light). Another view's casters in a view's shadow maps change none of its
pixels, by the second rule above. Each view keeps its own shadowed emitters and order.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..geometry import clip_polygon, plane_corners, visible_halfplanes
from ..scene import SceneSequence, ViewScene, occluder_radius
from .footprints import PaintingPart, lookup_ranges, painting_parts
from .settings import RenderSettings
from .visibility import balls_may_be_seen, shadow_may_fall_on_ball, shadow_may_reach

__all__ = ["SHADOW_READ_TEXELS", "SOFT_REACH_MAX", "SPLIT_MIN_PIXELS", "ViewPlan", "lookup_margins", "plan_views",
           "shadow_margin", "soft_reach", "soft_reach_balls", "whole_lights"]

SPLIT_MIN_PIXELS = 64 * 64
"""The fewest pixels (``H * W`` of what the camera draws) whose painting draw is split by shadow
footprints (``RenderSettings.split_shadow_lookups``). The split costs about 0.3 ms of planning and
part draws per view whatever the size, and saves lookups in proportion to the pixels: on
``misaligned`` (``python -m benchmarks.setting_cost --field split_shadow_lookups --values false true``,
CPU time, median paired difference, 2026-11-28, load 1.1-1.3 on 2 cores) it cost +0.24 ms per 24x32
view (+5.3 %, 40 sequences; 86 % of the lookups kept) and +0.10 ms per 48x64 view (+1.8 %, 30), and
saved 1.02 ms per 96x128 view (-11.8 %, 30; 41 % kept): the two meet near 64 x 64. Either way gives the same
bytes (``tests/render/test_skips.py``; the stored samples, 48x64, are drawn whole)."""

SHADOW_READ_TEXELS = 3.0
"""How far (texels, along each map axis) from a point's shadow-map coordinate its lookup may read
a texel's depth: ``shaders/spot_shadow.glsl`` takes 4 hardware-filtered taps half a texel off
the point, each reading the 2 x 2 texels around it, so texel centres within 1.5 texels; the
transmittance lookup reads the 2 x 2 texels of a map of half the resolution, so centres within 2
depth-map texels; the other 1 covers float32 rounding. A texel an occluder covers has its centre inside the occluder's
projection, so a lookup farther than this from every occluder's projection is unchanged by it."""

SHADOW_FRUSTUM_PAD = math.pi / 32
"""pyrender's spot-light shadow camera has a square frustum of half-angle ``outer_cone + pi / 32``.
It holds the light's cone, so a point whose lookup falls outside the map (and reads its clamped
edge) gets no light from it anyway; a frustum narrower than the cone would void that."""


def shadow_margin(outer_cone: float, map_size: int) -> float:
    """Angle (rad) that bounds :data:`SHADOW_READ_TEXELS` of a spot light's shadow map.

    The map spans ``2 tan(a)`` of the light's tangent plane over ``map_size`` texels (``a`` the
    frustum's half-angle), and an angle is at most the tangent-plane distance it spans; the
    read reaches ``SHADOW_READ_TEXELS`` texels along each axis, so ``sqrt(2)`` times that across.
    A frustum fitted more tightly has smaller texels, so the margin still holds.

    Args:
        outer_cone: the light's outer cone half-angle, radians.
        map_size: shadow-map side, texels.
    """
    half = outer_cone + SHADOW_FRUSTUM_PAD
    if half >= math.pi / 2:
        return math.inf
    return math.sqrt(2) * SHADOW_READ_TEXELS * 2 * math.tan(half) / map_size


SOFT_REACH_MAX = 0.5
"""Largest reach (tangent units) of a soft shadow lookup around its own direction (:func:`soft_reach`)."""


def soft_reach(emitter: np.ndarray, centres: np.ndarray, radii: np.ndarray, light_radius: float) -> float:
    """How far from its own direction, in tangent units of the emitter's frame, a soft shadow lookup
    (``light_radius`` above 0, ``shaders/spot_shadow.glsl``) reads the map: the widest penumbra any of
    the view's occluder balls can throw, ``light_radius`` over the distance of the nearest ball's
    surface (a penumbra is ``light_radius (w_r - w_b) / (w_b w_r)`` for a caster at depth ``w_b`` and
    a receiver at ``w_r``), at most :data:`SOFT_REACH_MAX`; 0 without a radius or occluders.

    Args:
        emitter: ``(3,)`` world position; centres, radii: ``(B, 3)``, ``(B,)`` the occluders' balls.
    """
    if light_radius <= 0 or len(radii) == 0:
        return 0.0
    nearest = float((np.linalg.norm(np.asarray(centres).reshape(-1, 3) - emitter, axis=1) - radii).min())
    return light_radius / nearest if nearest * SOFT_REACH_MAX > light_radius else SOFT_REACH_MAX


def soft_reach_balls(view: ViewScene, light_radius: float) -> tuple[np.ndarray, np.ndarray]:
    """The occluders' balls :func:`soft_reach` measures from: centres ``(B, 3)`` and radii ``|scale|``
    ``(B,)``; none without a ``light_radius`` (the reach is then 0 whatever they are)."""
    if light_radius <= 0:
        return np.zeros((0, 3)), np.zeros(0)
    return (np.array([occ.position for occ in view.occluders]).reshape(-1, 3),
            np.array([np.linalg.norm(occ.scale) for occ in view.occluders]))


def lookup_margins(view: ViewScene, emitters: list[tuple[int, int]], map_size: int, light_radius: float) -> np.ndarray:
    """``(E,)`` angles (rad) around which each emitter's lookups read its map: the filter's
    (:func:`shadow_margin`) plus the soft reach (:func:`soft_reach`; a tangent offset spans at most
    that angle), with the occluders' balls of radius ``|scale|``, as the shader's reach has them
    (``ShadowMaps.add_lights``)."""
    centres, radii = soft_reach_balls(view, light_radius)
    return np.array([shadow_margin(view.lights[a].outer_cone, map_size)
                     + soft_reach(view.lights[a].emitters[b], centres, radii, light_radius) for a, b in emitters])


@dataclass(frozen=True)
class ViewPlan:
    """What one view draws.

    Attributes:
        order: every emitter as ``(light, emitter)`` indices of ``view.lights``, in the order they
            are added to the scene: the shadowed ones first.
        n_shadowed: how many of ``order`` get a shadow map and lookup.
        drawn: indices of ``view.occluders`` drawn in the colour pass (and, if opaque enough,
            the mask).
        casters: indices of ``view.occluders`` drawn into the shadow maps.
        painting_parts: the screen rectangles the painting's colour draw is split into, each with
            the shadowed emitters it looks up (``render.footprints``); empty: one draw with every
            lookup.
    """

    order: tuple[tuple[int, int], ...]
    n_shadowed: int
    drawn: frozenset[int]
    casters: frozenset[int]
    painting_parts: tuple[PaintingPart, ...] = ()


def plan_views(sequence: SceneSequence, settings: RenderSettings,
               canvas_sizes: list[tuple[int, int]] | None = None) -> list[ViewPlan]:
    """The plan of every view of ``sequence`` (see the module docstring).

    Args:
        sequence: the scenes (the painting of ``sequence.image_size``).
        settings: the renderer's; its ``shadow_map_size``, ``shadows``, ``occluders_visible`` and
            the skips count here. ``skip_idle_shadows`` false: every emitter of a view with
            occluders is shadowed, and every occluder is a caster. ``cull_occluders`` false: every
            occluder is a caster, and drawn when occluders are visible.
        canvas_sizes: per view, the ``(H, W)`` pixels its camera draws (``render.canvas``); default
            ``sequence.image_size`` for every view.
    """
    first = sequence.views[0]
    shared = all(v.lights == first.lights and v.occluders == first.occluders for v in sequence.views)
    frames = [tuple(sequence.image_size)] * len(sequence.views) if canvas_sizes is None else list(canvas_sizes)
    facts = [_ViewFacts(view, sequence.image_size, frame, settings) for view, frame in zip(sequence.views, frames)]
    casting = [{e for e in f.emitters if f.drawn or f.hits[e]} for f in facts]
    plans = []
    for view, f, cast in zip(sequence.views, facts, casting):
        if settings.group_emitters:  # a light's emitters are shaded together: shadowed all or none
            lights = {a for a, _ in cast}
            cast = {e for e in f.emitters if e[0] in lights}
        # The same order whatever is skipped: the shader sums lights in this order.
        order = tuple(sorted(f.emitters, key=lambda e: e not in cast))
        if not (settings.shadows and view.occluders):
            cast = set()
        elif not settings.skip_idle_shadows:
            cast = set(f.emitters)
        casters = f.drawn.union(*(f.hits[e] for e in cast))
        drawn = f.drawn
        if not (settings.cull_occluders and settings.skip_idle_shadows):
            casters = frozenset(range(len(view.occluders)))
        if not settings.cull_occluders:
            drawn = casters if settings.occluders_visible else frozenset()
        plans.append(ViewPlan(order, len(cast), frozenset(drawn), frozenset(casters)))
    if shared and settings.cull_occluders:
        casters = frozenset().union(*(p.casters for p in plans))
        plans = [replace(p, casters=casters) for p in plans]
    if settings.split_shadow_lookups:
        plans = [_with_painting_parts(view, p, frame, settings) for view, p, frame in zip(sequence.views, plans, frames)]
    return plans


def whole_lights(begin: np.ndarray, end: np.ndarray, lights: list[int]) -> tuple[np.ndarray, np.ndarray]:
    """Lookup ranges widened to whole lights, for a shader that shades a light's emitters together.

    Args:
        begin, end: per-tile ranges of indices into ``lights`` (:func:`~.footprints.lookup_ranges`);
            ``begin == end``: no lookup.
        lights: the light of each shadowed emitter, in lookup order (a light's emitters adjacent).

    Returns:
        ``begin`` moved back to its light's first emitter and ``end`` on to just past its light's last;
        empty ranges stay empty.
    """
    lights = np.asarray(lights)
    new_light = np.r_[True, lights[1:] != lights[:-1]]
    starts = np.flatnonzero(new_light)
    stops = np.r_[starts[1:], len(lights)]
    light_of = np.cumsum(new_light) - 1  # each emitter's run
    empty = begin == end
    wide_begin = np.where(empty, begin, starts[light_of[np.minimum(begin, len(lights) - 1)]])
    wide_end = np.where(empty, end, stops[light_of[np.maximum(end - 1, 0)]])
    return wide_begin, wide_end


def _with_painting_parts(view: ViewScene, plan: ViewPlan, size: tuple[int, int], settings: RenderSettings) -> ViewPlan:
    """``plan`` with the painting's draw over the camera's ``size (H, W)`` pixels split by shadow footprints
    (``render.footprints``), unless every part would need every lookup or the view has fewer than
    :data:`SPLIT_MIN_PIXELS` pixels."""
    if not plan.n_shadowed or size[0] * size[1] < SPLIT_MIN_PIXELS:
        return plan
    emitters = list(plan.order[:plan.n_shadowed])
    margins = lookup_margins(view, emitters, settings.shadow_map_size, settings.light_radius)
    begin, end = lookup_ranges(view, emitters, sorted(plan.casters), margins, size, settings.footprint_tile)
    if settings.group_emitters:
        begin, end = whole_lights(begin, end, [a for a, _ in emitters])
    if (begin == 0).all() and (end == plan.n_shadowed).all():
        return plan
    return replace(plan, painting_parts=tuple(painting_parts(begin, end, size, settings.footprint_tile)))


class _ViewFacts:
    """One view's drawn occluders, and for each emitter the other occluders whose shadow from it
    may be read by a lookup of the view (``hits``): on the painting the camera sees, or on a drawn
    occluder. Drawn occluders shadow themselves, so with any of them every emitter casts. ``size``: the
    painting's ``(H, W)``; ``frame``: the pixels the camera draws."""

    def __init__(self, view: ViewScene, size: tuple[int, int], frame: tuple[int, int], settings: RenderSettings):
        cam, map_size = view.camera, settings.shadow_map_size
        self.emitters = [(a, b) for a, light in enumerate(view.lights) for b in range(len(light.emitters))]
        centres = np.array([occ.position for occ in view.occluders]).reshape(-1, 3)
        radii = np.array([occluder_radius(occ) for occ in view.occluders])
        seen = balls_may_be_seen(cam.K, cam.R, cam.t, frame, centres, radii) if settings.occluders_visible else []
        self.drawn = frozenset(i for i, visible in enumerate(seen) if visible)
        self.hits: dict[tuple[int, int], frozenset[int]] = {e: frozenset() for e in self.emitters}
        hidden = np.array([i for i in range(len(radii)) if i not in self.drawn], dtype=int)
        if not (self.emitters and len(hidden)):
            return
        emitters = np.array([view.lights[a].emitters[b] for a, b in self.emitters])
        margins = lookup_margins(view, self.emitters, map_size, settings.light_radius)
        region = clip_polygon(plane_corners(size)[:, :2], visible_halfplanes(cam.K, cam.R, cam.t, frame))
        drawn = sorted(self.drawn)
        hit = shadow_may_reach(emitters, centres[hidden], radii[hidden], region, margins) \
            | shadow_may_fall_on_ball(emitters, centres[hidden], radii[hidden], centres[drawn], radii[drawn],
                                      margins).any(axis=2)
        for e, row in zip(self.emitters, hit):
            self.hits[e] = frozenset(int(i) for i in hidden[row])
