"""Recorded values that hold on any machine: pixels by exact digest, geometry by value within a
stated tolerance.

Pixels come from the rasteriser, so their SHA-256 digests are compared only on the one they were
recorded on (``testsets.same_rasteriser``: the GL renderer and its GL version, which names Mesa's
release). Geometry (cameras, homographies, the fit error) is float64 arithmetic whose last
bits differ between kornia, numpy and BLAS builds, so it is recorded as numbers and compared within
a tolerance far below anything that moves a pixel:

- arrays (``K``, ``R``, ``t``, ``homographies``): ``|now - recorded| <= RTOL * max|recorded|``,
  relative to the array's largest entry (so exact zeros of an identity compare sensibly);
- ``homography_error`` (pixels, about 1e-14 for an exact fit): ``|now - recorded| <= ERROR_ATOL``.

The versions that produced a record are stored beside it (:func:`environment`).
"""

from __future__ import annotations

import hashlib
import importlib.metadata
import platform
from typing import Any

import numpy as np

from sidar_torch.evaluation.testsets import rasteriser_name, same_rasteriser
from sidar_torch.render.context import current_rasteriser

RTOL = 1e-9
"""Tolerance of a recorded geometry array, relative to its largest entry."""
ERROR_ATOL = 1e-12
"""Absolute tolerance of a recorded ``homography_error`` (pixels)."""
VERSIONED = ("torch", "kornia", "numpy", "scipy", "pyrender2", "trimesh", "Pillow", "PyOpenGL")


def environment() -> dict[str, str]:
    """What produced a record: Python, the rasteriser (``current_rasteriser``: GL renderer and
    version) and the versions of the packages that compute pixels and geometry. Call it after
    rendering (it asks the current GL context)."""
    versions = {name: importlib.metadata.version(name) for name in VERSIONED}
    return {"python": platform.python_version(), **current_rasteriser(), **versions}


def rasteriser_mismatch(recorded: dict[str, str]) -> str | None:
    """``None`` where pixels recorded on ``recorded`` (a record's ``recorded_with`` / ``recorded_on``)
    compare byte for byte in this process (``testsets.same_rasteriser``); otherwise why not, in words.
    Call it after rendering (it asks the current GL context)."""
    here = current_rasteriser()
    if same_rasteriser(recorded, here):
        return None
    return f"recorded on {rasteriser_name(recorded)!r}, this is {rasteriser_name(here)!r}"


def digest(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def geometry_record(value: Any) -> dict[str, Any]:
    """A JSON-able record of a number or array: ``{"dtype", "shape", "values"}`` (values as nested
    lists of Python floats or ints, which JSON round-trips exactly)."""
    array = np.asarray(value.numpy() if hasattr(value, "numpy") else value)
    return {"dtype": str(array.dtype), "shape": list(array.shape), "values": array.tolist()}


def mismatches(name: str, recorded: dict[str, Any], now: dict[str, Any]) -> list[str]:
    """Every way record ``now`` differs from ``recorded``: geometry records (``"values"``) within
    tolerance, records of several fields (``"fields"``) field by field, any other record (a digest,
    a text, a list of names) exactly."""
    if "values" in recorded:
        return [message for message in [geometry_mismatch(name, recorded, now)] if message]
    if "fields" in recorded:
        if sorted(now.get("fields", {})) != sorted(recorded["fields"]):
            return [f"{name}: fields {sorted(now.get('fields', {}))}, recorded {sorted(recorded['fields'])}"]
        return [message for field, value in recorded["fields"].items()
                for message in mismatches(f"{name}:{field}", value, now["fields"][field])]
    return [] if now == recorded else [f"{name}: differs from the recorded {sorted(recorded)[0]}"]


def geometry_mismatch(name: str, recorded: dict[str, Any], now: dict[str, Any]) -> str | None:
    """Why ``now`` is not ``recorded`` within the tolerance of entry ``name`` (``homography_error``
    absolute, any other array relative), or None if it is."""
    if (now["dtype"], now["shape"]) != (recorded["dtype"], recorded["shape"]):
        return f"{name}: {now['dtype']} {now['shape']}, recorded {recorded['dtype']} {recorded['shape']}"
    expected, actual = np.asarray(recorded["values"], float), np.asarray(now["values"], float)
    deviation = float(np.max(np.abs(actual - expected), initial=0.0))
    if name.endswith("homography_error"):
        bound = ERROR_ATOL
    else:
        bound = RTOL * float(np.max(np.abs(expected), initial=0.0))
    if not deviation <= bound:
        return f"{name}: differs from the recorded value by {deviation:.3g} (tolerance {bound:.3g})"
    return None
