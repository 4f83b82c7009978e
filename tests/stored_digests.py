"""Stored records of a few samples of every preset: a guard that a refactor changes no byte.

``python tests/stored_digests.py --write`` records them (run it only in a commit whose purpose is to
change samples, and say so in the commit message); ``--write --only NAME ...`` re-records only the
entries of those presets (the others and the recorded versions are kept, so the GL renderer and
versions must be the recorded ones); ``tests/test_stored_digests.py`` compares.

Pixels (``PIXEL_KEYS``) are stored as SHA-256 digests and compared only where the GL renderer
string is the one they were recorded on; geometry (homographies, cameras, the fit error) is stored
as numbers and compared everywhere within the tolerances of ``recorded.py``; keys, shapes and
dtypes must match exactly. The versions that made the record are stored with it.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from recorded import environment, geometry_record  # noqa: E402
from conftest import sample_digest  # noqa: E402

STORE = HERE / "data" / "sample_digests.json"
SIZE = (48, 64)
N_VIEWS = 3
INDICES = (0, 1)
SEED = 3
PIXEL_KEYS = ("images", "masks", "opacities", "shadow_masks", "shadow_free", "depth", "flow_to_reference", "label")
EVERYTHING_ON = dict(opacity_output=True, shadow_mask_output=True, shadow_free_output=True, depth_output=True, flow_output=True,
                     background="view",
                     exposure_jitter=True, sensor_noise=True, jpeg=True, mesh_detail="auto", n_occluders=(3, 3))
"""Overrides of the extra ``misaligned+everything`` entry: the optional outputs and view effects."""


def sample_record(sample: dict) -> dict[str, dict]:
    """``{key: {"sha256": ...}}`` for the pixel keys and the index, ``{key: {"text": ...}}`` for a string
    (``lens_model``), ``{key: geometry_record}`` for the rest."""
    digests = sample_digest(sample)
    return {key: {"sha256": digests[key]} if key in PIXEL_KEYS or key == "index"
            else {"text": value} if isinstance(value, str) else geometry_record(value)
            for key, value in sample.items()}


def current_records(names: list[str] | None = None) -> dict[str, dict[str, dict]]:
    """``{"name/index": sample_record}`` for every preset (and ``misaligned+everything``), or only
    ``names`` of them, and ``INDICES`` at ``SIZE``."""
    from sidar_torch import SidarDataset, available_presets, load_config

    configs = {preset: load_config(preset, image_size=SIZE, n_views=N_VIEWS) for preset in available_presets()}
    configs["misaligned+everything"] = configs["misaligned"].replace(**EVERYTHING_ON)
    unknown = sorted(set(names or []) - set(configs))
    if unknown:
        raise SystemExit(f"--only {unknown}: expected names among {sorted(configs)}")
    return {f"{name}/{index}": sample_record(SidarDataset(None, config, seed=SEED).sample(index))
            for name, config in configs.items() if names is None or name in names for index in INDICES}


if __name__ == "__main__":
    args = sys.argv[1:]
    if args[:1] != ["--write"] or (len(args) > 1 and (args[1] != "--only" or len(args) < 3)):
        raise SystemExit("usage: python tests/stored_digests.py --write [--only NAME ...]")
    only = args[2:] or None
    records = current_records(only)
    if only:
        stored = json.loads(STORE.read_text())
        if stored["recorded_with"] != environment():
            raise SystemExit(f"--only: this environment {environment()} is not the recorded one "
                             f"{stored['recorded_with']}")
        records = {**stored["samples"], **records}
    STORE.write_text(json.dumps({"recorded_with": environment(), "samples": records}, indent=1, sort_keys=True) + "\n")
    print(f"wrote {STORE} ({len(records)} samples" + (f", {only} re-recorded)" if only else ")"))
