"""Publish a test set: render it, record the SHA-256 of every exported file, write its definition.

    .venv/bin/python scripts/record_testset.py homography-v1

writes ``sidar_torch/evaluation/testsets/homography-v1.json`` from the draft below (the full config of each
category, its seed and count, the digests, the GL renderer and versions that recorded them). A
published definition is never rewritten (the script refuses): a change is a new name, ``-v2``.
"""

from __future__ import annotations

import argparse
import importlib.metadata
import json
import platform
import tempfile
from pathlib import Path

from sidar_torch.evaluation.testsets import (Category, TestSet, available_testsets, category_config,
                                                     export_testset, file_digests)

SIZE = {"image_size": (384, 512)}  # the paper's size

DRAFTS = {
    "homography-v1": {
        "task": "homography",
        "description": "Homography estimation between view 0 (fronto-parallel) and each other view of 4-view "
                       "384 x 512 sequences, 8 per artifact kind, built-in procedural paintings; shadow masks "
                       "rendered so that pairs are binned by shadowed fraction.",
        "pairs": "reference",
        "categories": [
            ("clean", "ambient light only, no occluders (geometry alone)", "ambient", {}),
            ("lights", "2-4 coloured spot, point and area lights, no occluders", "misaligned", {"n_occluders": (0, 0)}),
            ("shadows", "lights and 1-3 occluders out of sight that cast shadows", "shadows_only", {}),
            ("occlusions", "lights and 1-3 occluders in sight that cast no shadows", "occlusions_only", {}),
            ("all", "the misaligned preset: lights, 0-3 occluders in sight, shadows", "misaligned", {}),
        ],
        "overrides": {**SIZE, "n_views": 4, "shadow_mask_output": True},
        "seed": 36,
        "count": 8,
    },
    "shadow-removal-v1": {
        "task": "shadow-removal",
        "description": "Shadow removal: each view of 3-view 384 x 512 sequences against the same view with no "
                       "light blocked, scored inside and outside its shadow (shadow mask >= 0.1); occluders "
                       "out of sight (shadows) or in sight (all).",
        "pairs": "reference",
        "categories": [
            ("shadows", "lights and 1-3 occluders out of sight that cast shadows", "shadows_only", {}),
            ("all", "lights, 1-3 occluders in sight, shadows", "misaligned", {"n_occluders": (1, 3)}),
        ],
        "overrides": {**SIZE, "n_views": 3, "shadow_mask_output": True, "shadow_free_output": True},
        "seed": 36,
        "count": 6,
    },
}

VERSIONED = ("torch", "kornia", "numpy", "scipy", "pyrender2", "trimesh", "Pillow", "PyOpenGL")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("name", choices=sorted(DRAFTS))
    name = parser.parse_args().name
    target = Path(__file__).resolve().parents[1] / "sidar_torch" / "testsets" / f"{name}.json"
    if name in available_testsets() or target.exists():
        raise SystemExit(f"{name} is published ({target}); a change is a new name (-v2)")
    draft = DRAFTS[name]
    categories = tuple(Category(name=category, description=description,
                                config=category_config(preset, **overrides, **draft["overrides"]),
                                seed=draft["seed"], count=draft["count"])
                       for category, description, preset, overrides in draft["categories"])
    testset = TestSet(name=name, task=draft["task"], description=draft["description"], pairs=draft["pairs"],
                      categories=categories, digests={}, recorded_on={})
    with tempfile.TemporaryDirectory() as out:
        export_testset(testset, out)
        digests = file_digests(Path(out))
        recorded_on = {**categories[-1].dataset().renderer().rasteriser(), "python": platform.python_version(),
                       **{package: importlib.metadata.version(package) for package in VERSIONED}}
    definition = {"name": name, "task": testset.task, "description": testset.description, "pairs": testset.pairs,
                  "categories": [vars(category) for category in categories], "recorded_on": recorded_on,
                  "digests": digests}
    target.write_text(json.dumps(definition, indent=1) + "\n")
    print(f"wrote {target}: {len(categories)} categories, {len(digests)} file digests")


if __name__ == "__main__":
    main()
