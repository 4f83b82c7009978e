"""A sequence as named entries, the unit both export layouts write and read: per view the pixel
files of the sample table (:data:`sidar_torch.sample.KEYS`, column ``entry``: ``0.png``, ``0-m.png``,
..., 8-bit PNGs; ``0-d.npy``, float32, for the float outputs), the label ``gt.png`` and ``cameras.json``;
a new output is exported and read back without a change here. The writers (:mod:`.folders`, :mod:`.shards`) turn entries into bytes with
:mod:`.codecs`.
"""

from __future__ import annotations

from functools import partial
from typing import Any, Callable, Mapping

import numpy as np

from ..config.numbers import shown
from ..distortion import NO_LENS
from ..lens import distortion_maps
from ..sample import FLOAT_OUTPUTS, KEYS, SampleArrays, SampleKey, present_keys

__all__ = ["CAMERAS", "CAMERA_KEYS", "HOMOGRAPHIES", "camera_shape", "pixel_entries_text", "pixel_shape", "read_cameras",
           "sample_entries", "sample_from_entries"]

CAMERAS = "cameras.json"

HOMOGRAPHIES = "homographies.npy"
"""The file of all ``(V, V, 3, 3)`` float64 homographies, in Kornia pixels, of the layouts that write one
(shards, the paper's layout)."""

_NOT_IN_CAMERAS = {
    "homographies": "each layout writes them its own way (H_i_j.mat files, homographies.npy)",
    "index": "the sequence's folder or shard entry names it",
    "distortion_maps": "recomputed on reading from K and lens, by the function that made them (sidar_torch.lens)",
}
"""The keys without a file of their own that ``cameras.json`` does not hold, and why."""

CAMERA_KEYS: tuple[SampleKey, ...] = tuple(key for key in KEYS if key.entry is None and key.name not in _NOT_IN_CAMERAS)
"""The keys of :data:`sidar_torch.sample.KEYS` that ``cameras.json`` holds as JSON numbers (float64
when read): every key without a file of its own (``entry``), except :data:`_NOT_IN_CAMERAS`."""


def sample_entries(arrays: SampleArrays) -> dict[str, Any]:
    """The entries both layouts share, in writing order: per view the pixel keys of the
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
        **({} if arrays.lens is None else {"lens": arrays.lens.tolist()}),
        "frame": "OpenCV camera frame (x right, y down, z forward): world point X lands at K (R X + t); "
                 "K in pixels, Kornia pixel centres",
    }
    return entries


def pixel_entries_text() -> str:
    """The pixel files of a sequence, for help texts: ``"<i>.png (images), <i>-m.png (masks), ..."``."""
    return ", ".join(f"{key.entry.format(v='<i>')} ({key.name}{', with ' + key.switch if key.switch else ''})"
                     for key in KEYS if key.entry is not None)


def pixel_shape(key: SampleKey, image_size: tuple[int, int]) -> tuple[int, ...]:
    """The shape of one decoded file of pixel key ``key`` (a row of :data:`~sidar_torch.sample.KEYS`
    with an ``entry``): ``(H, W, C)`` for a key of ``C > 1`` channels (its table shape ``(..., C, H, W)``),
    else ``(H, W)``."""
    channels = int(key.shape.strip("()").split(", ")[-3])
    return (*image_size, channels) if channels > 1 else tuple(image_size)


def camera_shape(key: SampleKey, n_views: int) -> tuple[int, ...]:
    """The shape of key ``key`` (a row of :data:`CAMERA_KEYS`) in a sequence of ``n_views`` views: its
    table shape with ``V = n_views`` (``"(V, 3, 3)"`` -> ``(n_views, 3, 3)``, ``"()"`` -> ``()``)."""
    return tuple(n_views if axis == "V" else int(axis) for axis in key.shape.strip("()").split(", ") if axis)


def _numbers(cameras: dict[str, Any], name: str, shape: tuple[int, ...]) -> np.ndarray:
    """``cameras[name]`` as a float64 array of ``shape`` (``()``: one number), from nested JSON lists
    of numbers (NaN allowed: the paper's sequences have no cameras); ``ValueError`` naming the field
    otherwise (a bool, a string, an integer beyond float64, another shape)."""
    try:
        value = np.array(cameras.get(name), dtype=object)
    except ValueError:  # nested lists NumPy cannot make an array of
        value = np.array(None, dtype=object)
    if value.shape == shape and all(type(v) in (int, float) for v in value.flat):
        try:
            return value.astype(np.float64)
        except OverflowError:  # an integer beyond float64
            pass
    expected = f"{shape} numbers (nested lists)" if shape else "a number"
    raise ValueError(f"field {name!r}: expected {expected}, got {shown(cameras.get(name))}")


def read_cameras(cameras: Any, config: Mapping[str, Any]) -> dict[str, Any]:
    """The decoded ``cameras.json`` of a sequence of an export recorded with ``config``, checked:
    a JSON object whose ``image_size`` is the recorded one, with ``K``, ``R`` ``(V, 3, 3)`` and
    ``t`` ``(V, 3)`` numbers for the recorded ``n_views`` ``V``, a number ``homography_error`` and,
    recorded with a lens, ``lens`` ``(V, 5)``.

    Returns:
        ``{name: float64 array}`` for each key of :data:`CAMERA_KEYS`, of :func:`camera_shape` (``K``,
        ``R``, ``t``; ``homography_error`` 0-d).

    Raises:
        ValueError: the first field that is missing or wrong, by name (not the file's: the caller's).
    """
    if not isinstance(cameras, dict):
        raise ValueError(f"expected a JSON object of the cameras, got {shown(cameras)}")
    size, views = list(config["image_size"]), config["n_views"]
    if cameras.get("image_size", size) != size:
        raise ValueError(f"field 'image_size': the cameras' image_size {shown(cameras['image_size'])}, the recorded "
                         f"config's {size}")
    K = cameras.get("K")
    if isinstance(K, list) and len(K) != views:
        raise ValueError(f"field 'K': the cameras of {len(K)} views, but the recorded config field 'n_views' is {views}")
    present = present_keys(config)
    return {key.name: _numbers(cameras, key.name, camera_shape(key, views)) for key in CAMERA_KEYS if key in present}


def sample_from_entries(read: Callable[..., Any], index: int, config: Mapping[str, Any],
                        homographies: Callable[[int], np.ndarray]) -> SampleArrays:
    """Rebuild the :class:`SampleArrays` of sequence ``index`` from its decoded entries.

    Args:
        read: ``(entry name, shape, check)`` -> its decoded value, checked to be of ``shape`` (and of
            the keyword ``dtype``, passed for the float outputs' ``.npy`` files only; see
            :func:`.codecs.decode`) and passed through ``check`` (value -> value, or None); raises
            ``FileNotFoundError`` naming a missing entry and ``ValueError`` naming a malformed one
            (``check``'s errors included).
        index: the sequence's dataset index.
        config: the recorded config, its sizes checked (:func:`.limits.check_recorded_sizes`):
            the image size and view count every file must hold, and which keys are present
            (e.g. ``opacities``).
        homographies: ``V`` -> the ``(V, V, 3, 3)`` float64 homographies, read the layout's way.
    """
    cameras = read(CAMERAS, None, partial(read_cameras, config=config))
    n_views = len(cameras["K"])
    pixels = {}
    for key in present_keys(config):
        if key.entry is None:
            continue
        shape = pixel_shape(key, config["image_size"])
        # The float outputs' .npy files are read as float32; the 8-bit PNGs by their kind alone.
        kind = {"dtype": np.float32} if key.name in FLOAT_OUTPUTS else {}
        if "{v}" not in key.entry:
            pixels[key.name] = read(key.entry, shape, None, **kind)
            continue
        pixels[key.name] = np.stack([read(key.entry.format(v=v), shape, None, **kind) for v in range(n_views)])
    if config.get("distortion_map_output", False):
        maps = distortion_maps(config.get("lens_model", NO_LENS), cameras.get("lens"), cameras["K"], tuple(config["image_size"]))
        pixels["distortion_maps"] = np.ascontiguousarray(maps.transpose(0, 3, 1, 2), np.float32)
    return SampleArrays(**pixels, homographies=homographies(n_views), index=index, **cameras)
