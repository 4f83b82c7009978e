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

from ..config import SidarConfig
from ..config.numbers import shown
from ..choices.lenses import LENS_MODELS, NO_LENS, corner_coefficients, lens_folds
from ..sample.lens_views import distortion_maps
from ..sample import FLOAT_OUTPUTS, KEYS, SampleArrays, SampleKey, present_keys

__all__ = ["CAMERAS", "CAMERA_KEYS", "HOMOGRAPHIES", "camera_shape", "cameras_entry", "checked_homographies",
           "checked_homography", "lens_problem", "pixel_entries_text", "pixel_shape", "read_cameras", "sample_entries",
           "sample_from_entries", "unit_scaled"]

CAMERAS = "cameras.json"

HOMOGRAPHIES = "homographies.npy"
"""The file of all ``(V, V, 3, 3)`` float64 homographies, in Kornia pixels, of the layouts that write one
(shards, the paper's layout)."""

_NOT_IN_CAMERAS = {
    "homographies": "each layout writes them its own way (H_i_j.mat files, homographies.npy)",
    "index": "the sequence's folder or shard entry names it",
    "distortion_maps": "recomputed on reading from K and lens, by the function that made them (sidar_torch.sample.lens_views)",
    "lens_model": "the recorded config's lens_model (export.json) names it",
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
    of numbers; ``ValueError`` naming the field otherwise (a bool, a string, an integer beyond float64,
    another shape). What the numbers must be: :func:`_check_cameras`."""
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
    values = {key.name: _numbers(cameras, key.name, camera_shape(key, views)) for key in CAMERA_KEYS if key in present}
    _check_cameras(values, config)
    return values


ROTATION_TOLERANCE = 1e-6
"""Most ``|R R^T - I|`` of a camera's rotation (a float64 rotation is orthonormal to about 1e-15)."""


def _check_cameras(values: Mapping[str, np.ndarray], config: Mapping[str, Any]) -> None:
    """Check the numbers of a sequence's cameras (as :func:`read_cameras` returns them), view by view:
    ``K`` finite pinhole intrinsics ``[[fx, s, cx], [0, fy, cy], [0, 0, 1]]`` with ``fx, fy > 0``,
    ``R`` a rotation, ``t`` finite, ``homography_error`` a finite number ``>= 0`` and, with a lens,
    each view's ``lens`` one that :func:`lens_problem` finds nothing wrong with.

    Raises:
        ValueError: naming the first wrong field and view (not the file: the caller's).
    """
    K, R, t, error = values["K"], values["R"], values["t"], values["homography_error"]
    for v in range(len(K)):
        if not (np.isfinite(K[v]).all() and K[v, 0, 0] > 0 and K[v, 1, 1] > 0 and K[v, 1, 0] == 0
                and (K[v, 2] == (0, 0, 1)).all()):
            raise ValueError(f"field 'K': view {v}: expected finite pinhole intrinsics [[fx, s, cx], [0, fy, cy], "
                             f"[0, 0, 1]] with fx, fy > 0, got {shown(K[v].tolist())}")
        if not (np.isfinite(R[v]).all() and np.abs(R[v] @ R[v].T - np.eye(3)).max() <= ROTATION_TOLERANCE
                and np.linalg.det(R[v]) > 0):
            raise ValueError(f"field 'R': view {v}: expected a rotation (R R^T = I within {ROTATION_TOLERANCE:g}, "
                             f"det 1), got {shown(R[v].tolist())}")
        if not np.isfinite(t[v]).all():
            raise ValueError(f"field 't': view {v}: expected finite numbers, got {shown(t[v].tolist())}")
        if "lens" in values:
            problem = lens_problem(config["lens_model"], values["lens"][v], K[v], tuple(config["image_size"]))
            if problem:
                raise ValueError(f"field 'lens': view {v}: {problem}")
    if not (np.isfinite(error) and error >= 0):
        raise ValueError(f"field 'homography_error': expected a finite number >= 0 (pixels), got {float(error)!r}")


LENS_BOUNDS_SLACK = 1e-9
"""How far beyond its config field's bounds a coefficient at the image's corner may be read back
(the round trip through the lens in normalised coordinates moves it by about 1e-16)."""


def lens_problem(model: str, lens: np.ndarray, K: np.ndarray, image_size: tuple[int, int]) -> str | None:
    """Why ``lens (5,)`` float64 is not a lens of ``model`` that a config allows for a view of ``K (3, 3)``
    and ``image_size (H, W)``, or None: its coefficients must be finite, those at the image's corner
    (:func:`sidar_torch.choices.lenses.corner_coefficients`) within their config fields' bounds, those the
    model has none of 0, and the lens must not fold the view over the image
    (:func:`sidar_torch.choices.lenses.lens_folds`)."""
    if not np.isfinite(lens).all():
        return f"expected finite coefficients, got {shown(lens.tolist())}"
    corner = corner_coefficients(model, lens, K, image_size)
    for i, (name, value) in enumerate(zip(LENS_MODELS[model].fields, corner)):
        if name is None:
            if lens[i] != 0:
                return f"coefficient {i} is {lens[i]:.6g}, expected 0: lens_model {model!r} has no such coefficient"
            continue
        low, high = SidarConfig.__dataclass_fields__[name].metadata["bounds"]
        if not low - LENS_BOUNDS_SLACK <= value <= high + LENS_BOUNDS_SLACK:
            return (f"a coefficient at the image's corner is {value:.6g}, outside the bounds [{low:g}, {high:g}] of "
                    f"config field {name!r} (lens {shown(lens.tolist())})")
    if lens_folds(model, corner):
        return f"expected a lens that does not fold the view over the image, got {shown(lens.tolist())}"
    return None


def cameras_entry(read: Callable[..., Any], config: Mapping[str, Any]) -> dict[str, np.ndarray]:
    """The checked cameras of a sequence from its ``cameras.json`` (:func:`read_cameras`; ``read`` as
    :func:`sample_from_entries`'s)."""
    return read(CAMERAS, None, partial(read_cameras, config=config))


def sample_from_entries(read: Callable[..., Any], index: int, config: Mapping[str, Any],
                        homographies: Callable[[int], np.ndarray],
                        cameras: Callable[[Callable[..., Any], Mapping[str, Any]], dict[str, np.ndarray]] = cameras_entry
                        ) -> SampleArrays:
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
        cameras: ``(read, config)`` -> the checked cameras (:meth:`.layout.Layout.read_cameras`; by
            default those of ``cameras.json``, :func:`cameras_entry`).
    """
    cameras = cameras(read, config)
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
    lens_model = config.get("lens_model", NO_LENS)
    if config.get("distortion_map_output", False):
        maps = distortion_maps(lens_model, cameras.get("lens"), cameras["K"], tuple(config["image_size"]))
        pixels["distortion_maps"] = np.ascontiguousarray(maps.transpose(0, 3, 1, 2), np.float32)
    return SampleArrays(**pixels, homographies=homographies(n_views), index=index,
                        lens_model=None if lens_model == NO_LENS else lens_model, **cameras)


HOMOGRAPHY_CONDITION_LIMIT = 1e12
"""Largest condition number of a homography read from a file (the paper's sequences: at most 3e5 at
512 x 384; its inverse then keeps 4 digits or more)."""


def unit_scaled(H: np.ndarray) -> np.ndarray:
    """``H`` (finite, not all zeros) scaled by a power of two, exactly, to ``0.5 <= max|H| < 1``."""
    return np.ldexp(H, -np.frexp(np.abs(H).max())[1])


def checked_homography(H: np.ndarray) -> np.ndarray:
    """``H`` ``(3, 3)`` float64 as it is, checked to be an invertible homography whatever its scale:
    finite, not zero, condition number at most :data:`HOMOGRAPHY_CONDITION_LIMIT`.

    Raises:
        ValueError: saying which (the caller names the file).
    """
    expected = (f"expected an invertible homography (3 x 3 finite numbers, condition number at most "
                f"{HOMOGRAPHY_CONDITION_LIMIT:g})")
    if H.shape != (3, 3):
        raise ValueError(f"{expected}, got shape {H.shape}")
    if not np.isfinite(H).all() or not H.any():
        raise ValueError(f"{expected}, got {shown(H.tolist())}")
    singular = np.linalg.svd(unit_scaled(H), compute_uv=False)
    if not singular[0] <= HOMOGRAPHY_CONDITION_LIMIT * singular[-1]:
        condition = singular[0] / singular[-1] if singular[-1] > 0 else np.inf
        raise ValueError(f"{expected}, got one of condition number {condition:.3g}: {shown(H.tolist())}")
    return H


def checked_homographies(H: np.ndarray) -> np.ndarray:
    """``H`` ``(V, V, 3, 3)`` float64, each ``H[i, j]`` checked by :func:`checked_homography` (and
    kept as it is); ``ValueError`` naming the first wrong pair."""
    for i, j in np.ndindex(H.shape[:2]):
        try:
            checked_homography(H[i, j])
        except ValueError as error:
            raise ValueError(f"H[{i}, {j}]: {error}") from None
    return H
