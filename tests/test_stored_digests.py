"""Samples of every preset match the stored records (see ``stored_digests.py``): pixels byte for
byte on the recorded rasteriser, geometry within ``recorded.py``'s tolerances everywhere."""

import json

import numpy as np
import pytest

from recorded import geometry_record, mismatches, rasteriser_mismatch
from stored_digests import PIXEL_KEYS, STORE, current_records


def test_geometry_is_compared_within_its_tolerance_and_no_further():
    H = np.array([[1.0, 2e-3, 5.0], [0.0, 1.0, -3.0], [1e-4, 0.0, 1.0]])
    recorded = geometry_record(H)
    assert mismatches("H", recorded, geometry_record(H * (1 + 1e-14) + 1e-16)) == []  # round-off
    assert mismatches("H", recorded, geometry_record(H + np.eye(3) * 1e-7)) != []     # a real change
    assert mismatches("H", recorded, geometry_record(H.astype(np.float32))) != []     # another dtype
    assert mismatches("s: homography_error", geometry_record(3e-15), geometry_record(9e-15)) == []
    assert mismatches("sample: homography_error", geometry_record(0.0), geometry_record(2e-12)) != []
    cameras = {"fields": {"K": geometry_record(np.eye(3)), "frame": {"text": "OpenCV"}}}
    assert mismatches("c", cameras, {"fields": {"K": geometry_record(np.eye(3)), "frame": {"text": "GL"}}}) != []
    assert mismatches("png", {"sha256": "ab"}, {"sha256": "ab"}) == []
    assert mismatches("png", {"sha256": "ab"}, {"sha256": "cd"}) != []


@pytest.mark.gl  # renders
def test_samples_of_every_preset_match_the_stored_records():
    stored = json.loads(STORE.read_text())
    now = current_records()
    assert sorted(now) == sorted(stored["samples"]), "presets or indices differ from the stored ones"
    mismatch = rasteriser_mismatch(stored["recorded_with"])  # after rendering: it asks the current context
    differences = []
    for name, records in now.items():
        expected = stored["samples"][name]
        assert sorted(records) == sorted(expected), f"{name}: sample keys differ"
        differences += [difference for key, record in records.items() if key not in PIXEL_KEYS or mismatch is None
                        for difference in mismatches(f"{name}: {key}", expected[key], record)]
    assert not differences, "\n".join(differences)
    if mismatch is not None:
        pytest.skip(f"pixels not compared: {mismatch}")
