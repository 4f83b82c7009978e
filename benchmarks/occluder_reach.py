"""Where a preset's occluders fall, from the scene sampler's draws alone (nothing is rendered).

For ``--samples`` sequences of ``--config`` (``sample_sequence``, seed 0): the share of occluder
centres that lie over the painting in their view (in front of the camera, inside the image, and on
the painting along the camera's ray through them), for view 0 and for the other views; and how often
a placement drawn from the config's occluder box would put an occluder's bounding sphere around one
of the sequence's cameras (the sampler then draws another: ``scene.sampler._sample_occluder``),
estimated with ``--placements`` fresh draws from the box per occluder.

    python -m benchmarks.occluder_reach --config paper_misaligned --samples 2000
    python -m benchmarks.occluder_reach --config paper_misaligned --samples 2000 --set reference_height=[0,0]
"""

from __future__ import annotations

import argparse

import numpy as np

from .common import parse_set

__all__ = ["build_parser", "centre_over_painting", "main"]


def centre_over_painting(K: np.ndarray, R: np.ndarray, t: np.ndarray, size: tuple[int, int],
                         centre: np.ndarray) -> bool:
    """Whether the world point ``centre (3,)`` lies over the painting in the view of camera ``K, R, t``
    (Kornia pixels, OpenCV frame) of ``size = (H, W)``: in front of the camera, its pixel inside the
    image, and the camera's ray through it meeting the plane ``z = 0`` within the painting."""
    from sidar_torch.geometry import plane_size

    cam = R @ centre + t
    if cam[2] <= 0:
        return False
    u, v, _ = K @ cam / cam[2]
    h, w = size
    if not (-0.5 <= u <= w - 0.5 and -0.5 <= v <= h - 0.5):
        return False
    origin = -R.T @ t
    if centre[2] >= origin[2]:
        return False
    hit = origin + (centre - origin) * origin[2] / (origin[2] - centre[2])
    width, height = plane_size(size)
    return abs(hit[0]) <= width / 2 and abs(hit[1]) <= height / 2


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``python -m benchmarks.occluder_reach``; parsing it runs nothing."""
    parser = argparse.ArgumentParser(prog="python -m benchmarks.occluder_reach", description=__doc__.splitlines()[0])
    parser.add_argument("--config", default="paper_misaligned", help="preset name or YAML path (default paper_misaligned)")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="config overrides (YAML values)")
    parser.add_argument("--samples", type=int, default=2000, help="sequences drawn (default 2000)")
    parser.add_argument("--placements", type=int, default=20, help="fresh box draws per occluder (default 20)")
    return parser


def main(argv: list[str] | None = None) -> None:
    from sidar_torch import load_config
    from sidar_torch.scene import sample_sequence

    args = build_parser().parse_args(argv)
    try:
        config = load_config(args.config, **parse_set(args.set))
    except ValueError as error:
        raise SystemExit(f"occluder_reach: {error}") from error
    if args.samples < 1 or args.placements < 1:
        raise SystemExit("occluder_reach: --samples and --placements must be at least 1")
    rng = np.random.default_rng(0)
    over = {0: [], 1: []}
    enclosing = []
    for index in range(args.samples):
        sequence = sample_sequence(config, np.random.default_rng([0, index]))
        cameras = np.stack([view.camera.position for view in sequence.views])
        for j, view in enumerate(sequence.views):
            for occluder in view.occluders:
                over[min(j, 1)].append(centre_over_painting(view.camera.K, view.camera.R, view.camera.t,
                                                            config.image_size, occluder.position))
                xy = rng.uniform(-config.occluder_xy, config.occluder_xy, size=(args.placements, 2))
                z = rng.uniform(*config.occluder_height, size=(args.placements, 1))
                fresh = np.concatenate([xy, z], axis=1)
                gap = np.linalg.norm(fresh[:, None] - cameras[None], axis=2).min(axis=1)
                enclosing.append((gap <= np.linalg.norm(occluder.scale)).mean())
    print(f"{args.config} {' '.join(args.set)}: {args.samples} sequences, "
          f"{len(over[0]) + len(over[1])} occluders")
    print(f"occluder centres over the painting: view 0 {np.mean(over[0]):.3f} ({len(over[0])}), "
          f"views 1.. {np.mean(over[1]):.3f} ({len(over[1])})")
    print(f"placements whose bounding sphere holds a camera of the sequence: {np.mean(enclosing):.4f}")


if __name__ == "__main__":
    main()
