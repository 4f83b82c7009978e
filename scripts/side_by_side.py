"""A figure of the paper's renders beside ours, on the same paintings.

For each sequence folder of ``--anchors`` (made by the paper's own generator: views ``0.png ..
5.png`` and the painting ``source.png``, as ``benchmarks/realism.py`` reads them), one row of the
paper's views and, below it, one row of ours: sample 0 of
``SidarDataset(source=[that source.png], config=load_config(--config, image_size=(H, W)), seed=k)``
for the ``k``-th folder. Both rows are shrunk to ``--thumb`` and written as one JPEG.

    .venv/bin/python scripts/side_by_side.py --anchors DIR --out docs/side_by_side.jpg
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from PIL import Image

from sidar_torch import SidarDataset, load_config


def _row(images: list[np.ndarray], thumb: tuple[int, int]) -> np.ndarray:
    """``(h, n w, 3)`` uint8: the ``(H, W, 3)`` images shrunk to ``thumb = (h, w)`` side by side."""
    h, w = thumb
    return np.concatenate([np.asarray(Image.fromarray(i).resize((w, h), Image.LANCZOS)) for i in images], axis=1)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--anchors", required=True, help="folder of the paper generator's sequence folders")
    parser.add_argument("--config", default="paper_misaligned", help="preset name or YAML path of our rows")
    parser.add_argument("--sequences", type=int, default=3, help="sequence folders shown (the first, by name)")
    parser.add_argument("--views", type=int, default=4, help="views per row")
    parser.add_argument("--thumb", type=int, nargs=2, default=(144, 192), metavar=("H", "W"))
    parser.add_argument("--out", default="docs/side_by_side.jpg")
    args = parser.parse_args()
    folders = sorted(p for p in Path(args.anchors).iterdir() if (p / "source.png").is_file())[:args.sequences]
    if not folders:
        raise SystemExit(f"--anchors: no folder with a source.png in {args.anchors}")
    rows = []
    for k, folder in enumerate(folders):
        paper = [np.asarray(Image.open(folder / f"{v}.png").convert("RGB")) for v in range(args.views)]
        config = load_config(args.config, image_size=paper[0].shape[:2], n_views=args.views)
        ours = SidarDataset(source=[str(folder / "source.png")], config=config, seed=k).sample(0)["images"]
        ours = list(ours.mul(255).round().byte().permute(0, 2, 3, 1).numpy())
        rows += [_row(paper, args.thumb), _row(ours, args.thumb)]
        print(f"{folder.name}: the paper's views 0-{args.views - 1} above ours ({args.config}, seed {k}, sample 0)")
    Image.fromarray(np.concatenate(rows, axis=0)).save(args.out, quality=88)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
