"""Warming a renderer up: every shader variant a config can need, compiled before its first sample.

llvmpipe compiles a fragment-shader variant the first time a program is drawn with a new
combination of GL state (program defines, blending, bound texture layout, draw buffers,
multisampling): 0.1-0.3 s each with a cold cache, about 1.3 s in all for the first ``misaligned``
sample at 384x512, against 0.25 s for the sample itself. Samples meet the variants in whatever
order their scenes bring them (a transparent caster, a glass occluder, a view whose lights shade
nothing), so without a warm-up a later sample now and then pays a compile in the middle of a stream.

:func:`warm_up_sequence` builds, from a config, one small sequence whose views meet every variant
that config's samples can draw: view 0's camera, lights and painting material of a sample of the
config, and small spheres above the painting's centre, one per distinct variant of the materials
its ``occluder_materials`` kinds draw (:func:`variant_signature`), in

1. a view with every occluder (shadowed lights, transmittance maps if a caster transmits, every
   mirror variant),
2. a view with the occluders whose shadows are opaque (shadowed lights without transmittance),
3. the first view without its lights (every occluder drawn with the unshadowed programs),
4. a view without occluders (the painting's unshadowed program),
5. for every number of light groups a view of the config can have (:func:`light_group_counts`), the
   first view with that many lights, once with every occluder and once without (the painting's
   program for that count, drawn beside the shadow maps and without them).

With a lens (``lens_model`` not ``"none"``) every view also has the identity lens of the config's model, so
the warm-up compiles the resampling pass's program that most views take (``render.resample``).

A renderer renders it once (``SceneRenderer.warm_up``, through :func:`warm_up_renderer`): it hands out
no sample and changes no pixel of later samples (``tests/render/test_warm_up.py``). Who owns a renderer
warms it up; the path that makes a sample (``sample.render_arrays``) takes a renderer and compiles
nothing ahead. The owners: ``SidarDataset`` (``SidarDataset.warm_up`` before the first sample; else
``SidarDataset.renderer`` after the renderer's first sample, which compiles only what it draws, and
before its second), and ``SidarAugment`` and its render pool's workers (before their first batch or
task). A process that may fork renders in a render process (``render.process``), which keeps Mesa's disk
cache: the variants it compiles are loaded, not compiled, by every later process and by the DataLoader
workers it forks. Where a process renders in itself (``render.render_in_this_process``: benchmarks, the
tests), a forked worker takes over its parent's renderer (``render.renderer.shared_renderer``): if the
parent rendered, or called ``SidarDataset.warm_up``, the worker compiles nothing at all.

A renderer that is about to compile because Mesa's cache lacks the config's variants says so once on
stderr first (:func:`announce_compiles`); a marker file in the cache folder, written after a warm-up,
tells which settings and variants the cache holds.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import os
import sys
from dataclasses import replace
from pathlib import Path
from itertools import cycle, islice
from typing import TYPE_CHECKING, Hashable

import numpy as np

from ..choices.lenses import NO_LENS
from ..config import SidarConfig
from ..render import RenderProcess
from ..render.context import may_fork
from ..config.memory import shadowed_emitters
from ..scene import MATERIAL_KINDS, Material, Occluder, SceneSequence, sample_sequence
from ..version import __version__

if TYPE_CHECKING:  # the renderer's module imports pyrender; rendering imports it at first use
    from ..render import SceneRenderer

__all__ = ["COLD_COMPILE_S", "WARM_UP_SEED", "announce_compiles", "light_group_counts", "variant_signature",
           "warm_up_renderer", "warm_up_sequence"]

WARM_UP_SEED = 0x5EED
"""Seed of the generator that draws the warm-up scene (any fixed value: the scene is never handed out)."""

_DRAWS_PER_KIND = 8
"""Materials drawn per kind when collecting variants, so that a kind whose draws can land in
different variants shows each with high odds (today every kind's draws share one, but for
draws of probability 0: a ``principled`` material without any specular layer, a glass of index 1)."""

_HEIGHT, _RADIUS, _SPACING = 0.1, 0.03, 0.08
"""The spheres: centre height above the painting, radius and spacing along x (painting units; the
painting's shorter side is 1), so that each is seen by view 0 and shadows the painting under it."""


def variant_signature(material: Material) -> tuple[str | None, bool, bool]:
    """What of an occluder's ``material`` picks its shader variants: its mirror define
    (``render.mirror.mirror_define``), whether it is blended (transparent), and whether its shadow
    goes to the depth maps (opaque, or ``opaque_shadow``) rather than the transmittance maps."""
    from ..render.mirror import mirror_define  # imports pyrender: at the first warm-up, not with the package

    return mirror_define(material), material.transparent, not material.transparent or material.opaque_shadow


def light_group_counts(config: SidarConfig) -> tuple[int, ...]:
    """The numbers of light groups (``render.passes.light_group_count``) whose painting
    programs the warm-up draws: each count from one to ``passes.UNROLLED_LIGHT_GROUPS``
    that a view of ``config`` may have (a program each), then one above if a view may have more (the
    program with the loop). A light is one group with ``area_light_shading: per_light``, each of its
    emitters one with ``per_emitter``."""
    from ..render.passes import UNROLLED_LIGHT_GROUPS  # imports OpenGL: at the first warm-up

    most = config.n_lights[1] if config.area_light_shading == "per_light" else shadowed_emitters(config)
    counts = tuple(range(max(config.n_lights[0], 1), min(most, UNROLLED_LIGHT_GROUPS) + 1))
    return counts + (UNROLLED_LIGHT_GROUPS + 1,) if most > UNROLLED_LIGHT_GROUPS else counts


def _variant_materials(config: SidarConfig, rng: np.random.Generator) -> list[Material]:
    """One material per distinct :func:`variant_signature` among draws of ``config.occluder_materials``."""
    found: dict[tuple, Material] = {}
    for kind in config.occluder_materials:
        for _ in range(_DRAWS_PER_KIND):
            material = MATERIAL_KINDS[kind](rng, config)
            found.setdefault(variant_signature(material), material)
    return [found[key] for key in sorted(found, key=repr)]


def warm_up_sequence(config: SidarConfig) -> SceneSequence:
    """The warm-up scenes of ``config`` (see the module docstring), at ``config.image_size``.

    Their lights are those of the first of up to 64 samples of the config (seed :data:`WARM_UP_SEED`)
    whose view 0 has a light, so that the shadowed variants are met whenever the config can draw a
    light; with ``n_lights = (0, 0)`` the views have none, and with ``n_occluders = (0, 0)`` no
    occluder.
    """
    rng = np.random.default_rng(WARM_UP_SEED)
    for _ in range(64):
        first = sample_sequence(config, rng).views[0]
        if first.lights or config.n_lights[1] == 0:
            break
    materials = _variant_materials(config, rng) if config.n_occluders[1] > 0 else []
    x = (np.arange(len(materials)) - (len(materials) - 1) / 2) * _SPACING
    spheres = tuple(Occluder("sphere", np.array([xk, 0.0, _HEIGHT]), np.eye(3), np.full(3, _RADIUS), material)
                    for xk, material in zip(x, materials))
    opaque = tuple(o for o in spheres if variant_signature(o.material)[2])
    views = (replace(first, occluders=spheres), replace(first, occluders=opaque),
             replace(first, occluders=spheres, lights=()), replace(first, occluders=()))
    for count in light_group_counts(config) if first.lights else ():
        # One-emitter lights (a group each, whatever area_light_shading says), copied from the first's.
        lights = tuple(replace(light, emitters=light.emitters[:1]) for light in islice(cycle(first.lights), count))
        views += (replace(first, occluders=spheres, lights=lights), replace(first, occluders=(), lights=lights))
    if config.lens_model == NO_LENS:
        return SceneSequence(tuple(config.image_size), views)
    # The identity lens of the config's model: its resampling program, which most views take (2 Newton
    # steps of an iterative model; a view whose lens needs more compiles its program at its first use).
    return SceneSequence(tuple(config.image_size), views, lens_model=config.lens_model, lenses=np.zeros((len(views), 5)))


@functools.lru_cache(maxsize=32)
def _scenes_and_key(config: SidarConfig) -> tuple[SceneSequence, Hashable]:
    """:func:`warm_up_sequence` of ``config`` and what it warms up: whether it has lights, the numbers
    of light groups of its views and the :func:`variant_signature` s of its occluders (configs that
    agree on these need one warm-up)."""
    sequence = warm_up_sequence(config)
    signatures = sorted({variant_signature(o.material) for v in sequence.views for o in v.occluders}, key=repr)
    lit = bool(sequence.views[0].lights)
    return sequence, (lit, light_group_counts(config) if lit else (), config.lens_model, *signatures)


def warm_up_renderer(renderer: SceneRenderer, config: SidarConfig) -> bool:
    """Compile in ``renderer`` every shader variant ``config``'s samples can need: the first call for a
    renderer and what the config warms up renders :func:`warm_up_sequence` (``SceneRenderer.warm_up``),
    later ones return at once; a forked worker's renderer, taken over from its parent, comes warm if the
    parent's was.

    Args:
        renderer: a ``SceneRenderer`` made for ``config`` (``RenderSettings.from_config(config)``).
        config: what the samples will be drawn from.

    Returns:
        Whether it rendered (False: warm for ``config`` already).
    """
    if renderer.renders == 0:
        announce_compiles(renderer, config)
    rendered = renderer.warm_up(*_scenes_and_key(config))
    marker = _cache_marker(renderer, config) if rendered else None
    if marker is not None:
        marker.parent.mkdir(parents=True, exist_ok=True)
        marker.touch()
    return rendered


COLD_COMPILE_S = 4
"""Seconds the first sample and the warm-up of the ``misaligned`` preset spend compiling with a cold cache,
on one idle core (2.7 s and 1.6 s at 384x512 measured, 2026-11-28): what :func:`announce_compiles` says."""

_ANNOUNCED: set[Path] = set()


def announce_compiles(renderer: SceneRenderer, config: SidarConfig) -> None:
    """Say once per process on stderr, before ``renderer``'s first render, that it will compile its shader
    variants and for about how long, where Mesa's disk cache will keep them but does not yet: where
    :func:`warm_up_renderer` never finished for these settings and this config's variants with this cache
    folder (a marker file in it). Silent where the renderer works without the cache (a context of a
    process that may fork, ``render.context``), which compiles in every process."""
    marker = _cache_marker(renderer, config)
    if marker is None or marker.exists() or marker in _ANNOUNCED:
        return
    _ANNOUNCED.add(marker)
    print(f"sidar_torch: compiling the renderer's shader variants for this config (about {COLD_COMPILE_S} s on an "
          f"idle core with Mesa's llvmpipe, once: the driver's shader cache keeps them for later processes; "
          f"Mesa's is in {marker.parents[1]})", file=sys.stderr)


def _cache_marker(renderer: SceneRenderer, config: SidarConfig) -> Path | None:
    """The file whose presence says that Mesa's disk cache holds every shader variant of ``config`` for
    ``renderer``'s settings (written after a warm-up), in Mesa's cache folder (``MESA_SHADER_CACHE_DIR``,
    else ``$XDG_CACHE_HOME/mesa_shader_cache``, else ``~/.cache/mesa_shader_cache``), so that emptying it
    removes the marker too; None where ``renderer`` renders without the cache."""
    in_render_process = isinstance(renderer, RenderProcess)
    disabled = os.environ.get("MESA_SHADER_CACHE_DISABLE", "false").lower() in ("true", "1", "yes")
    if disabled or not (in_render_process or not may_fork()):
        return None
    home = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    folder = Path(os.environ.get("MESA_SHADER_CACHE_DIR") or Path(home) / "mesa_shader_cache")
    fields = {name: sorted(value) if isinstance(value, frozenset) else value
              for name, value in dataclasses.asdict(renderer.settings).items()}
    key = json.dumps([__version__, fields, repr(_scenes_and_key(config)[1])], default=str, sort_keys=True)
    return folder / "sidar_torch-warm" / hashlib.sha256(key.encode()).hexdigest()[:20]
