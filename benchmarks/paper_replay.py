"""The paper generator's own scenes, rendered by ours: its draws replayed, no Blender needed.

The SIDAR generator (github niika/SIDAR, ``main.py`` with ``--n_cameras 5 --homography`` and its defaults
``--n_lights 2 5 --n_objects 0 4``) draws everything from numpy's global generator, in a fixed order:
the painting's Principled material, the five cameras (``scene.add_cameras``: x, y, z, an unused field of
view, the lens), then per view (``scene.generate_scene``) the painting's material again, the lights
(``add_illumination``: position, kind, power and cone or spread, HSV colour) and the occluders
(``objects.add_objects``: position, Euler angles, scale, shape, material kind and its factors).
:func:`paper_draws` replays that order with ``np.random.seed(seed)`` (how the reference sequences were
seeded: seed ``NN`` for sequence ``NN``, their cameras come out exactly, ``tests/benchmarks/test_paper_replay.py``),
and :func:`paper_sequence` turns one sequence's draws into our ``SceneSequence``: Blender units / 7, the
lights' powers as our intensities (``P / (4 pi 7^2)``; area ``P / (pi 7^2)``, then its spread,
``scene.spread_beam``), Blender's spot size and blend, the cameras' lens on a 36 mm sensor and
Blender's aim (``rotation_difference`` of +z to the camera's position), the plane's factors (its
reflectance ``((ior - 1) / (ior + 1))^2 2 level``), the occluders' Euler rotations and scales (the
torus never scaled). The occluders' materials are drawn by our kinds (``--config``'s
``paper_occluder_materials``), from a generator of their own: the rows compared are the painting's
exposure and the masks.

Two uses:

* ``--anchors DIR`` alone: each reference sequence's own scenes through our renderer, view by view
  against Blender's render of them (exposure of the painting pixels both renders see; occluder rows
  from each mask): what is left is the renderer's difference, not the draws'.
* ``--population N``: ``N`` replayed sequences (seeds ``1001 ..``) against ``N`` of ``--config``
  (seed 0), both through our renderer with the reference paintings (``index % 6``): the samplers'
  difference, with 6 N views each instead of the references' 36.

    python -m benchmarks.paper_replay --anchors DIR
    python -m benchmarks.paper_replay --anchors DIR --population 180 --config paper_misaligned
"""

from __future__ import annotations

import argparse
import colorsys
import math
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks.common import parse_set

BLENDER_UNITS = 7.0
"""Blender units per painting unit (the generator's plane is 7 units on its shorter side)."""

SENSOR_MM = 36.0
"""Blender's default sensor width, fitted to the longer image side."""

PAPER_KINDS = {"Glossy": "metallic", "Transparent": "transparent", "Refraction": "glass", "Glass": "glass",
               "Principled": "principled"}
"""The generator's occluder material -> our kind (as ``paper_misaligned``'s ``occluder_materials`` maps them)."""

POPULATION_SEED = 1001
"""First seed of the replayed population (the reference sequences used 1-6)."""


def _principled(r: Any) -> dict:
    return dict(base=r.uniform(0, 1, 4), roughness=r.uniform(0, 0.5), ior=r.uniform(1, 2), metallic=r.uniform(0, 1),
                specular=r.uniform(0, 1), transmission=r.uniform(0, 1), coat=r.uniform(0, 1),
                coat_roughness=r.uniform(0, 1))


def _material(r: Any, kind: str) -> dict:
    if kind == "Glossy":
        return dict(kind=kind, color=r.uniform(0, 1, 4), roughness=r.uniform(0, 0.5))
    if kind in ("Glass", "Refraction"):
        return dict(kind=kind, color=r.uniform(0, 1, 4), roughness=r.uniform(0, 0.5), ior=r.uniform(1, 2))
    if kind == "Transparent":
        return dict(kind=kind, color=r.uniform(0, 1, 4))
    return dict(kind=kind, **_principled(r))


def _light(r: Any) -> dict:
    light = dict(position=np.array([r.uniform(-10, 10), r.uniform(-10, 10), r.uniform(10, 15)]))
    light["type"] = kind = str(r.choice(["POINT", "SPOT", "AREA"]))
    if kind == "POINT":
        light["energy"] = r.uniform(1000, 3500)
    if kind == "SPOT":
        light.update(energy=r.uniform(1000, 10000), size=r.uniform(10 * np.pi / 180, 90 * np.pi / 180),
                     blend=r.uniform(0, 1))
    if kind == "AREA":
        light.update(energy=r.uniform(1000, 2000), spread=r.uniform(10 * np.pi / 180, 90 * np.pi / 180))
    light["hsv"] = (r.uniform(0, 1), r.uniform(0, 0.3))
    return light


def _occluder(r: Any) -> dict:
    position = np.array([r.uniform(-3, 3), r.uniform(-3, 3), r.uniform(1, 5)])
    euler, scale = r.uniform(0, 2 * np.pi, 3), r.uniform(0.1, 1.1, 3)
    shape = str(r.choice(["Cone", "Sphere", "Cylinder", "Torus", "Cube"]))
    kind = str(r.choice(["Glossy", "Transparent", "Refraction", "Glass", "Principled"]))
    return dict(position=position, euler=euler, scale=scale, shape=shape, material=_material(r, kind))


def paper_draws(seed: int, n_cameras: int = 5, n_lights: tuple[int, int] = (2, 5),
                n_objects: tuple[int, int] = (0, 4)) -> tuple[list[dict], list[dict]]:
    """The draws of one run of the generator seeded with ``np.random.seed(seed)``, in its order.

    Returns:
        cameras: ``n_cameras`` dicts (``position (3,)`` Blender units, ``lens`` mm), views 1..;
        views: ``n_cameras + 1`` dicts of ``plane`` (Principled factors), ``lights`` and ``objects``.
    """
    r = np.random.RandomState(seed)  # the legacy generator np.random.seed seeds: the same stream
    _principled(r)  # main.py's first add_plane, redrawn for every view
    cameras = []
    for _ in range(n_cameras):
        position = np.array([r.uniform(-5, 5), r.uniform(-5, 5), r.uniform(5, 7)])
        r.uniform(30, 90)  # a field of view the lens then overrides
        cameras.append(dict(position=position, lens=r.uniform(15, 30)))
    views = []
    for _ in range(n_cameras + 1):
        plane = _principled(r)
        lights = [_light(r) for _ in range(r.randint(*n_lights))]
        views.append(dict(plane=plane, lights=lights, objects=[_occluder(r) for _ in range(r.randint(*n_objects))]))
    return cameras, views


def blender_aim(position: np.ndarray) -> np.ndarray:
    """World-to-camera ``R (3, 3)`` (OpenCV frame) of a Blender camera at ``position`` turned by
    ``Vector((0, 0, 1)).rotation_difference(position)``: the shortest turn of +z onto its position,
    so its -z axis looks at the origin."""
    from scipy.spatial.transform import Rotation

    direction = position / np.linalg.norm(position)
    axis = np.cross([0.0, 0.0, 1.0], direction)
    sin = np.linalg.norm(axis)
    turn = np.eye(3) if sin < 1e-12 else Rotation.from_rotvec(axis / sin * math.atan2(sin, direction[2])).as_matrix()
    return np.diag([1.0, -1.0, -1.0]) @ turn.T


def _our_light(light: dict, size: tuple[int, int]) -> Any:
    from sidar_torch.scene import Light
    from sidar_torch.scene.description import FALLOFFS
    from sidar_torch.scene.kinds import _covering_beam, spread_beam

    position = light["position"] / BLENDER_UNITS
    colour = np.array(colorsys.hsv_to_rgb(light["hsv"][0], light["hsv"][1], 1.0))
    intensity = light["energy"] / (4 * np.pi * BLENDER_UNITS**2)
    if light["type"] == "SPOT":
        outer = light["size"] / 2
        inner = math.acos(math.cos(outer) + (1 - math.cos(outer)) * light["blend"])
        return Light("spot", position[None], colour, intensity, inner, outer, smooth_falloff=True)
    cover = _covering_beam(position, np.zeros((1, 2)), 1.0, size)  # cones over the whole painting, not moved
    if light["type"] == "POINT":
        return Light("point", cover.emitters, colour, intensity, cover.inner_cone, cover.outer_cone)
    distance = float(np.linalg.norm(position))
    cos = position[2] / distance
    inner, outer, centre = spread_beam(math.degrees(light["spread"]),
                                       light["energy"] / (np.pi * BLENDER_UNITS**2) * cos / distance**2)
    return Light("area", cover.emitters, colour, centre * distance**2 / cos, inner, outer, FALLOFFS["area_spread"])


def paper_sequence(cameras: list[dict], views: list[dict], size: tuple[int, int], config: Any,
                   rng: np.random.Generator) -> Any:
    """Our ``SceneSequence`` of one replayed run (:func:`paper_draws`), ``size = (H, W)``; ``config``'s
    kinds draw the occluders' materials from ``rng`` (nothing else is drawn)."""
    from sidar_torch import geometry
    from sidar_torch.scene import Camera, Material, Occluder, SceneSequence, ViewScene
    from sidar_torch.scene.kinds import MATERIAL_KINDS, PAPER_TORUS_SCALE

    h, w = size
    ours = [Camera(*geometry.reference_camera(size, 10 / BLENDER_UNITS))]
    for camera in cameras:
        position = camera["position"] / BLENDER_UNITS
        R = blender_aim(position)
        f = camera["lens"] / SENSOR_MM * max(h, w)
        ours.append(Camera(np.array([[f, 0, (w - 1) / 2], [0, f, (h - 1) / 2], [0, 0, 1.0]]), R, -R @ position))
    scenes = []
    for camera, view in zip(ours, views):
        p = view["plane"]
        reflectance = ((p["ior"] - 1) / (p["ior"] + 1)) ** 2 * 2 * p["specular"]
        plane = Material(np.ones(4), p["metallic"], p["roughness"], min(reflectance / 0.08, 1.0), p["coat"],
                         p["coat_roughness"], p["transmission"])
        occluders = tuple(Occluder(o["shape"].lower(), o["position"] / BLENDER_UNITS,
                                   geometry.euler_rotation(o["euler"]),
                                   PAPER_TORUS_SCALE if o["shape"] == "Torus" else o["scale"] / BLENDER_UNITS,
                                   MATERIAL_KINDS[PAPER_KINDS[o["material"]["kind"]]](rng, config))
                          for o in view["objects"])
        scenes.append(ViewScene(camera, tuple(_our_light(light, size) for light in view["lights"]), occluders, plane, 0.0))
    return SceneSequence(size, tuple(scenes))


def view_rows(views: np.ndarray, masks: np.ndarray, H0: np.ndarray, hidden: np.ndarray | None = None) -> dict:
    """Per-view rows of one sequence (``views (V, H, W, 3)`` uint8, ``masks (V, H, W)`` bool, ``H0 (V, 3, 3)``
    from view 0 to each view, Kornia's convention): median luma, near-black and near-white fractions of the
    painting pixels (also hiding ``hidden (V, H, W)`` bool where given), mask components and coverage
    within the painting region (``benchmarks.realism``'s definitions); each ``(V,)``."""
    from benchmarks.exposure import view_exposure
    from benchmarks.images import painting_region
    from benchmarks.realism import occluder_components, occluder_coverage

    exposure = view_exposure(views, masks if hidden is None else masks | hidden)
    regions = [painting_region(H, views.shape[1:3]) for H in H0]
    return dict(median=exposure.median, black=exposure.black, white=exposure.white,
                components=np.array([occluder_components(m, r) for m, r in zip(masks, regions)]),
                coverage=np.array([occluder_coverage(m, r) for m, r in zip(masks, regions)]))


def _arrays(sample: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    from benchmarks.images import to_uint8

    return (to_uint8(sample["images"]), sample["masks"][:, 0].numpy() > 0.5,
            sample["homographies"].double().numpy()[0])


def summary(rows: list[dict[str, np.ndarray]]) -> str:
    """One line of the realism table's exposure and occluder rows over the views of ``rows``."""
    v = {k: np.concatenate([r[k] for r in rows]) for k in rows[0]}
    return (f"{len(v['median'])} views: median luma {np.median(v['median']):.0f} (mean {v['median'].mean():.0f}), "
            f"near-white median {np.median(v['white']):.3f} (mean {v['white'].mean():.3f}), near-black mean "
            f"{v['black'].mean():.3f}, dark views {np.mean(v['median'] < 50):.3f}, blown-out views "
            f"{np.mean(v['white'] > 0.10):.3f}, mostly black views {np.mean(v['black'] > 0.30):.3f}; views with an "
            f"occluder {np.mean(v['components'] > 0):.3f}, coverage median {np.median(v['coverage']):.3f} "
            f"(mean {v['coverage'].mean():.3f})")


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``python -m benchmarks.paper_replay``; parsing it runs nothing."""
    parser = argparse.ArgumentParser(prog="python -m benchmarks.paper_replay", description=__doc__.split("\n")[0])
    parser.add_argument("--anchors", required=True, type=Path, help="folder of the paper generator's sequences")
    parser.add_argument("--population", type=int, default=0,
                        help="replayed sequences (seeds 1001..) against as many of --config (0: the references only)")
    parser.add_argument("--config", default="paper_misaligned", help="preset (or YAML path) rendering both")
    parser.add_argument("--set", nargs="*", default=[], metavar="KEY=VALUE", help="config overrides (values as YAML)")
    return parser


def main(argv: list[str] | None = None) -> None:
    from benchmarks.images import anchor_sequences, read_rgb
    from benchmarks.realism import anchor_homographies
    from sidar_torch import SidarDataset, load_config
    from sidar_torch.sample import render_sample
    from sidar_torch.scene import sample_sequence

    args = build_parser().parse_args(argv)
    if args.population < 0:
        raise SystemExit(f"--population {args.population}: expected 0 or more")
    sequences = anchor_sequences(args.anchors)
    size = read_rgb(sequences[0] / "source.png").shape[:2]
    config = load_config(args.config, image_size=size, **parse_set(args.set))
    dataset = SidarDataset(source=[str(s / "source.png") for s in sequences], config=config, seed=0)
    paintings = [dataset.source.painting(k, size) for k in range(len(sequences))]

    def replayed(seed: int, painting: np.ndarray) -> dict:
        scene = paper_sequence(*paper_draws(seed), size, config, np.random.default_rng(seed))
        return render_sample(dataset.renderer(), scene, painting, config, seed, rng=np.random.default_rng(seed))

    def ours(index: int) -> dict:
        rng = dataset.generator(index)
        painting = paintings[index % len(paintings)]
        return render_sample(dataset.renderer(), sample_sequence(config, rng), painting, config, index, rng=rng)

    if args.population == 0:
        mine, theirs, drawn = [], [], []
        for k, sequence in enumerate(sequences):
            seed = int(sequence.name[-2:])  # seqNN was seeded with NN
            count = len(list(sequence.glob("[0-9]*-m.png")))
            views = np.stack([read_rgb(sequence / f"{j}.png") for j in range(count)])
            masks = np.stack([read_rgb(sequence / f"{j}-m.png")[..., 0] >= 128 for j in range(count)])
            our_views, our_masks, H0 = _arrays(replayed(seed, paintings[k]))
            drawn += [len(view["objects"]) for view in paper_draws(seed)[1]]
            mine.append(view_rows(our_views, our_masks, H0, masks))
            theirs.append(view_rows(views, masks, anchor_homographies(sequence, count, size)[0], our_masks))
        print(f"the references' own scenes (seeds {', '.join(s.name[-2:] for s in sequences)}), exposure where both "
              f"renders see the painting ({np.mean(drawn):.2f} occluders drawn per view, the generator's mean 1.5):"
              f"\n  Blender: {summary(theirs)}\n  ours:    {summary(mine)}")
        return
    paper = [view_rows(*_arrays(replayed(POPULATION_SEED + i, paintings[i % len(paintings)])))
             for i in range(args.population)]
    sampled = [view_rows(*_arrays(ours(i))) for i in range(args.population)]
    print(f"{args.population} sequences each, rendered by ours at {size[1]}x{size[0]} with the references' paintings"
          + (f", overrides {parse_set(args.set)}" if args.set else "")
          + f":\n  the paper's draws (seeds {POPULATION_SEED}..): {summary(paper)}\n  {args.config} (seed 0): "
          f"{summary(sampled)}")


if __name__ == "__main__":
    main()
