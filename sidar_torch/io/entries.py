"""A sequence as named entries, the unit both export layouts write and read: per view the 8-bit pixel
files of the sample table (:data:`sidar_torch.sample.KEYS`, column ``entry``: ``0.png``, ``0-m.png``,
...), the label ``gt.png`` and ``cameras.json``; a new 8-bit output is exported and read back
without a change here. The writers (:mod:`.folders`, :mod:`.shards`) turn entries into bytes with
:mod:`.codecs`.
"""

from __future__ import annotations

from typing import Any, Callable

import numpy as np

from ..sample import KEYS, SampleArrays, present_keys

__all__ = ["CAMERAS", "pixel_entries_text", "sample_entries", "sample_from_entries"]

CAMERAS = "cameras.json"


def sample_entries(arrays: SampleArrays) -> dict[str, Any]:
    """The entries both layouts share, in writing order: per view the 8-bit pixel keys of the
    sample table (``0.png``, ``0-m.png``, ``0-o.png`` if rendered, ...), then the whole-image ones
    (``gt.png``), then ``cameras.json`` (index, image size, K, R, t, homography error)."""
    n_views = len(arrays.images)
    pixel_keys = [key for key in KEYS if key.entry is not None and getattr(arrays, key.name) is not None]
    entries = {key.entry.format(v=v): getattr(arrays, key.name)[v]
               for v in range(n_views) for key in pixel_keys if "{v}" in key.entry}
    entries.update({key.entry: getattr(arrays, key.name) for key in pixel_keys if "{v}" not in key.entry})
    entries[CAMERAS] = {
        "index": arrays.index,
        "image_size": list(arrays.label.shape[:2]),
        "K": arrays.K.tolist(),
        "R": arrays.R.tolist(),
        "t": arrays.t.tolist(),
        "homography_error": arrays.homography_error,
        "frame": "OpenCV camera frame (x right, y down, z forward): world point X lands at K (R X + t); "
                 "K in pixels, Kornia pixel centres",
    }
    return entries


def pixel_entries_text() -> str:
    """The 8-bit pixel files of a sequence, for help texts: ``"<i>.png (images), <i>-m.png (masks), ..."``."""
    return ", ".join(f"{key.entry.format(v='<i>')} ({key.name}{', with ' + key.switch if key.switch else ''})"
                     for key in KEYS if key.entry is not None)


def sample_from_entries(read: Callable[[str], Any], index: int, config: dict[str, Any],
                        homographies: Callable[[int], np.ndarray]) -> SampleArrays:
    """Rebuild the :class:`SampleArrays` of sequence ``index`` from its decoded entries.

    Args:
        read: entry name -> decoded value (raises ``FileNotFoundError`` naming a missing entry).
        index: the sequence's dataset index.
        config: the recorded config (says which keys are present, e.g. ``opacities``).
        homographies: ``V`` -> the ``(V, V, 3, 3)`` float64 homographies, read the layout's way.
    """
    cameras = read(CAMERAS)
    n_views = len(cameras["K"])
    pixels = {}
    for key in present_keys(config):
        if key.entry is None:
            continue
        if "{v}" not in key.entry:
            pixels[key.name] = read(key.entry)
            continue
        views = [read(key.entry.format(v=v)) for v in range(n_views)]
        shapes = sorted({view.shape for view in views})
        if len(shapes) > 1:
            raise ValueError(f"SampleArrays.{key.name}: the files {key.entry.format(v='<v>')} of sequence {index} "
                             f"differ in shape: {shapes}")
        pixels[key.name] = np.stack(views)
    return SampleArrays(**pixels, homographies=homographies(n_views),
                        homography_error=float(cameras["homography_error"]),
                        K=np.array(cameras["K"], dtype=np.float64), R=np.array(cameras["R"], dtype=np.float64),
                        t=np.array(cameras["t"], dtype=np.float64), index=index)
