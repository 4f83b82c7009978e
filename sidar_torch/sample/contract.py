"""The sample contract: every key of a sample with its shape, dtype, meaning and when it is present
(:data:`KEYS`), the arrays a sample is made of (:class:`SampleArrays`) and their batching.

Every consumer goes through this module: :class:`sidar_torch.SidarDataset` and
:class:`sidar_torch.SidarAugment` hand out :meth:`SampleArrays.to_tensors`, export writes a
:class:`SampleArrays` and :class:`sidar_torch.ExportedDataset` rebuilds one from the files and
calls the same :meth:`SampleArrays.to_tensors`, so a set read back equals the rendered samples by
construction. An optional output is a row of ``choices.outputs.OUTPUTS`` (its switch, channels, file,
memory, values, meaning and producer); its row of :data:`KEYS`, its field of :class:`SampleArrays`, the
checks and the tensors follow the row (:mod:`.assembly` makes the arrays).

Shapes: ``V`` views of ``H x W`` pixels; a batch (DataLoader, ``SidarAugment``) adds a leading ``B``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np
import torch

from ..choices.lenses import LENS_MODELS, NO_LENS
from ..choices.outputs import OUTPUTS
from ..config import SidarConfig

__all__ = ["FLOAT_OUTPUTS", "GEOMETRY_DTYPES", "KEYS", "LENS_KEYS", "PIXEL_KEYS", "SampleArrays", "SampleKey", "float_tensor",
           "present_keys", "stack_arrays", "stack_samples"]


@dataclass(frozen=True)
class SampleKey:
    """One key of a sample dict.

    Attributes:
        name: the key (also the :class:`SampleArrays` field holding its values).
        shape: its shape in one sample.
        dtype: its dtype and range in a sample; ``geometry_dtype`` is the config field of that name
            (float32 by default, or float64).
        meaning: what the values are, with units and frames.
        switch: the config field that must be true for the key to be present (None: always).
        entry: for the 8-bit pixel keys, the name of its export file (``{v}`` is the view's
            number); None for the others (see :mod:`sidar_torch.io`).
    """

    name: str
    shape: str
    dtype: str
    meaning: str
    switch: str | None = None
    entry: str | None = None

    @classmethod
    def optional(cls, name: str) -> "SampleKey":
        """The key of the optional output ``name``: its row of ``choices.outputs.OUTPUTS`` gives all of it
        (switch, export entry, values, meaning and channels: the shape ``(V, C, H, W)``)."""
        row = OUTPUTS[name]
        return cls(name, f"(V, {row.channels}, H, W)", row.values, row.meaning, switch=row.switch, entry=row.entry)


KEYS: tuple[SampleKey, ...] = (
    SampleKey("images", "(V, 3, H, W)", "float32 in [0, 1], multiples of 1/255",
              "the views (sRGB); view 0 is the reference camera, fronto-parallel", entry="{v}.png"),
    SampleKey("masks", "(V, 1, H, W)", "float32 in {0, 1}",
              "1 where the painting is not visible (an occluder, or off the painting), 0 where it is",
              entry="{v}-m.png"),
    *(SampleKey.optional(name) for name in OUTPUTS),
    SampleKey("label", "(3, H, W)", "float32 in [0, 1], multiples of 1/255",
              "the painting in view 0's frame, unlit, unoccluded", entry="gt.png"),
    SampleKey("homographies", "(V, V, 3, 3)", "geometry_dtype",
              "H[i, j] maps view-i pixels to view-j pixels (Kornia pixels: pixel (u, v) is column u, row v, "
              "the centre of the top-left pixel is (0, 0)); det = 1; fitted in float64. With a lens, the maps "
              "between the undistorted views (sidar_torch.undistort)"),
    SampleKey("homography_error", "()", "float (Python)",
              "largest distance, in view-j pixels, between where the float64 homographies and the analytic "
              "plane-induced ones send the painting points both views of a pair see, on a 17 x 17 lattice "
              "(the fit is exact at its own four points, so its error shows elsewhere)"),
    SampleKey("K", "(V, 3, 3)", "geometry_dtype", "intrinsics, pixels (Kornia pixel centres); with a lens, the "
              "pinhole intrinsics of the undistorted view"),
    SampleKey("R", "(V, 3, 3)", "geometry_dtype",
              "world-to-camera rotation, OpenCV camera frame (x right, y down, z forward): world point X "
              "lands at K (R X + t)"),
    SampleKey("t", "(V, 3)", "geometry_dtype", "world-to-camera translation, painting units"),
    SampleKey("lens", "(V, 5)", "float64",
              "each view's lens in normalised camera coordinates K^-1 (u, v, 1): OpenCV's (k1, k2, p1, p2, k3) for "
              "lens_model brown_conrady (cv2.undistort(view, K, lens)), (lambda, 0, 0, 0, 0) for division "
              "(x_u = x_d / (1 + lambda |x_d|^2)); see sidar_torch.choices.lenses", switch="lens_model"),
    SampleKey("lens_model", "()", "str (Python)",
              "the lens model lens holds the coefficients of: the config's lens_model, 'brown_conrady' or "
              "'division' (sidar_torch.undistort reads it); a batch holds a list of B, as DataLoader collates "
              "strings", switch="lens_model"),
    SampleKey("distortion_maps", "(V, 2, H, W)", "float32",
              "per view and distorted pixel, where it comes from in the undistorted view (u then v, Kornia "
              "pixels; each pixel itself without a lens)", switch="distortion_map_output"),
    SampleKey("index", "()", "int (Python)", "the sample's dataset index (SidarAugment: its position in the batch)"),
)
"""The sample's keys, in the order of a sample dict."""

FLOAT_OUTPUTS = frozenset(name for name, row in OUTPUTS.items() if row.dtype == "float32")
"""The optional outputs of float32 values with units (``depth``): their arrays and tensors are float32,
their export files ``.npy``."""

PIXEL_KEYS = frozenset(key.name for key in KEYS if key.entry is not None and key.name not in FLOAT_OUTPUTS)
"""The 8-bit pixel keys of the table (those with an export entry, but the float outputs: ``images``,
``masks``, ``label`` and the optional ``opacities``, ``shadow_masks`` and ``shadow_free``)."""

LENS_KEYS = ("lens", "lens_model", "distortion_maps")
"""The keys the lens step makes (:mod:`sidar_torch.sample.lens_views`, from the config and the lenses), not the renderer:
the optional keys besides ``choices.outputs.OUTPUTS``' rows. ``lens`` and ``lens_model`` are turned on by
``lens_model`` (not ``"none"``), ``distortion_maps`` by ``distortion_map_output``; none has a file of its
own (``lens`` is in ``cameras.json``, ``lens_model`` in the export's recorded config, the maps are
recomputed on reading)."""

GEOMETRY_DTYPES = {"float32": torch.float32, "float64": torch.float64}
"""``geometry_dtype`` (config field) -> dtype of ``homographies``, ``K``, ``R`` and ``t``."""


def present_keys(config: SidarConfig | Mapping[str, Any]) -> tuple[SampleKey, ...]:
    """The keys a sample rendered with ``config`` (a config or its ``to_dict()``) holds: those without a
    switch, and those whose switch is true (``lens_model``: not ``"none"``)."""
    fields = config.to_dict() if isinstance(config, SidarConfig) else config
    return tuple(key for key in KEYS if key.switch is None or fields.get(key.switch, False) not in (False, NO_LENS))


def _with_output_fields(cls: type) -> type:
    """``cls`` with one field per optional output (``choices.outputs.OUTPUTS``, in its order, after the
    fields of the class body), ``None`` by default (not rendered): applied before ``dataclass``, so a
    new row is a new field without a line here."""
    for name in OUTPUTS:
        cls.__annotations__[name] = "np.ndarray | None"
        setattr(cls, name, None)
    return cls


@dataclass(frozen=True)
@_with_output_fields
class SampleArrays:
    """One sample as NumPy arrays: what the renderer made and export writes, exactly.

    Attributes (``V`` views of ``H x W`` pixels; see :data:`KEYS` for the meanings):
        images: ``(V, H, W, 3)`` uint8 sRGB.
        masks: ``(V, H, W)`` uint8, 255 where the painting is not visible, else 0.
        label: ``(H, W, 3)`` uint8 sRGB.
        homographies: ``(V, V, 3, 3)`` float64.
        homography_error: pixels.
        K, R: ``(V, 3, 3)``, t: ``(V, 3)`` float64.
        index: the dataset index.
        lens: ``(V, 5)`` float64, each view's lens (None: no lens).
        lens_model: the model of ``lens``, a row of :data:`sidar_torch.choices.lenses.LENS_MODELS` (None:
            no lens; given exactly when ``lens`` is).
        distortion_maps: ``(V, 2, H, W)`` float32 (None: not asked for).
        and one field per optional output, named as its row of ``choices.outputs.OUTPUTS`` (``opacities``,
            ``depth``, ...): ``(V, H, W)`` (one channel) or ``(V, H, W, C)`` (``C`` channels) of the row's
            dtype (uint8 or float32), or None (not rendered).

    Raises:
        ValueError: a field of another dtype or shape (named in the message).
    """

    images: np.ndarray
    masks: np.ndarray
    label: np.ndarray
    homographies: np.ndarray
    homography_error: float
    K: np.ndarray
    R: np.ndarray
    t: np.ndarray
    index: int
    lens: np.ndarray | None = None
    lens_model: str | None = None
    distortion_maps: np.ndarray | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.images, np.ndarray) or self.images.ndim != 4:
            raise ValueError(f"SampleArrays.images: expected a (V, H, W, 3) uint8 array, got "
                             f"{getattr(self.images, 'shape', type(self.images).__name__)}")
        V, H, W = self.images.shape[:3]
        expected = {"images": ((V, H, W, 3), np.uint8), "masks": ((V, H, W), np.uint8),
                    "label": ((H, W, 3), np.uint8), "homographies": ((V, V, 3, 3), np.float64),
                    "K": ((V, 3, 3), np.float64), "R": ((V, 3, 3), np.float64), "t": ((V, 3), np.float64)}
        for name, row in OUTPUTS.items():
            if getattr(self, name) is not None:
                expected[name] = ((V, H, W, row.channels) if row.channels > 1 else (V, H, W), np.dtype(row.dtype))
        for name, shape, dtype in (("lens", (V, 5), np.float64), ("distortion_maps", (V, 2, H, W), np.float32)):
            if getattr(self, name) is not None:
                expected[name] = (shape, dtype)
        for name, (shape, dtype) in expected.items():
            value = getattr(self, name)
            if not isinstance(value, np.ndarray) or value.shape != shape or value.dtype != dtype:
                got = f"{value.shape} {value.dtype}" if isinstance(value, np.ndarray) else type(value).__name__
                raise ValueError(f"SampleArrays.{name}: expected shape {shape} {np.dtype(dtype)}, got {got}")
        object.__setattr__(self, "lens_model", _checked_lens_model(self.lens_model, self.lens is not None))
        object.__setattr__(self, "homography_error", float(self.homography_error))
        object.__setattr__(self, "index", int(self.index))

    def to_tensors(self, geometry_dtype: str = "float32", pixel_dtype: torch.dtype = torch.float32) -> dict[str, Any]:
        """The sample dict (keys, shapes and dtypes of :data:`KEYS`), CPU tensors.

        Args:
            geometry_dtype: ``"float32"`` or ``"float64"``, the dtype of ``homographies``, ``K``,
                ``R`` and ``t`` (the config field of that name).
            pixel_dtype: the dtype of the pixel keys (:data:`PIXEL_KEYS`): a float dtype (float32, as
                :data:`KEYS` says, unless asked otherwise) holds ``k / 255`` for the 8-bit value
                ``k``; uint8 holds ``k``.
        """
        if geometry_dtype not in GEOMETRY_DTYPES:
            raise ValueError(f"geometry_dtype: expected one of {tuple(GEOMETRY_DTYPES)}, got {geometry_dtype!r}")
        _check_pixel_dtype(pixel_dtype)
        tensors = {}
        for name in _FIELDS:
            value = getattr(self, name)
            if name in PIXEL_KEYS and value is not None:
                levels = torch.from_numpy(value)
                levels = levels.movedim(-1, -3) if name in _COLOUR_KEYS else levels.unsqueeze(-3)
                tensors[name] = _levels_as(levels, pixel_dtype)
            elif name in FLOAT_OUTPUTS and value is not None:
                values = torch.from_numpy(value)
                tensors[name] = values.movedim(-1, -3) if OUTPUTS[name].channels > 1 else values.unsqueeze(-3)
            elif isinstance(value, np.ndarray):
                tensors[name] = torch.from_numpy(value).to(_OWN_DTYPES.get(name, GEOMETRY_DTYPES[geometry_dtype]))
            elif value is not None:
                tensors[name] = value
        return tensors


def _checked_lens_model(model: Any, has_lens: bool) -> str | None:
    """``SampleArrays.lens_model`` as a ``str`` (a NumPy string, as Ray's columns hold it, included), or
    None without a lens; ``ValueError`` unless it names a lens model exactly when there is a ``lens``."""
    if isinstance(model, (np.ndarray, np.str_)):  # a Ray column's 0-d string array, a NumPy string
        model = str(model)
    if (model is None) != (not has_lens) or (has_lens and model not in LENS_MODELS):
        expected = f"one of {sorted(LENS_MODELS)} (there is a lens)" if has_lens else "None (there is no lens)"
        raise ValueError(f"SampleArrays.lens_model: expected {expected}, got {model!r}")
    return model


_FIELDS = tuple(key.name for key in KEYS)

_OWN_DTYPES = {"lens": torch.float64, "distortion_maps": torch.float32}
"""The array keys whose dtype is their own, not ``geometry_dtype``."""

_COLOUR_KEYS = frozenset(key.name for key in KEYS if key.name in PIXEL_KEYS and key.shape.endswith("3, H, W)"))
"""The pixel keys of 3 channels, whose arrays end in that axis (moved before the rows in the tensors);
the others' tensors get an axis of one channel there."""


def float_tensor(batch: Mapping[str, Any], key: str, needs: str) -> torch.Tensor:
    """``batch[key]`` (a sample or batch dict), checked to be a float tensor.

    Raises:
        KeyError: no ``key``, naming it and what the caller ``needs``.
        ValueError: not a float tensor (naming its type or dtype).
    """
    if key not in batch:
        raise KeyError(f"batch: missing key {key!r} (needs {needs})")
    value = batch[key]
    if not isinstance(value, torch.Tensor) or not value.is_floating_point():
        raise ValueError(f"batch[{key!r}]: expected a float tensor, got {type(value).__name__}"
                         f"{'' if not isinstance(value, torch.Tensor) else ' of ' + str(value.dtype)}")
    return value


def _check_pixel_dtype(dtype: torch.dtype) -> None:
    if not (dtype == torch.uint8 or dtype.is_floating_point):
        raise ValueError(f"pixel_dtype: expected torch.uint8 or a float dtype, got {dtype}")


def _levels_as(levels: torch.Tensor, dtype: torch.dtype) -> torch.Tensor:
    """uint8 levels ``k`` as ``dtype``: themselves for uint8, else ``k / 255`` computed in ``dtype``
    (exact for 0 and 255), with the levels' strides."""
    return levels if dtype == torch.uint8 else levels.to(dtype).div_(255)


def stack_arrays(samples: Sequence[SampleArrays], geometry_dtype: str = "float32",
                 pixel_dtype: torch.dtype = torch.float32) -> dict[str, Any]:
    """The batch of ``samples``, ``stack_samples([s.to_tensors(geometry_dtype, pixel_dtype) for s in
    samples])`` value for value and stride for stride, with the pixels stacked as 8-bit levels and
    converted to ``pixel_dtype`` once for the whole batch (uint8: not at all).

    Raises:
        ValueError: no samples, or samples that differ in which keys they hold.
    """
    if not samples:
        raise ValueError("stack_arrays: expected at least one sample, got none")
    _check_pixel_dtype(pixel_dtype)
    tensors = [s.to_tensors(geometry_dtype, torch.uint8) for s in samples]
    for name in _FIELDS:
        if len({name in t for t in tensors}) > 1:
            raise ValueError(f"stack_arrays: {name} is present in some samples and not in others")
    return {name: _levels_as(value, pixel_dtype) if name in PIXEL_KEYS else value
            for name, value in stack_samples(tensors).items()}


def stack_samples(samples: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """Batch sample dicts of one config: every tensor key stacked (a leading ``B``),
    ``homography_error`` as ``(B,)`` float64, ``index`` as ``(B,)`` int64 and ``lens_model`` as a list
    of ``B`` strings, what ``DataLoader``'s default collation gives these Python values, so a batch is
    the same whoever made it (``DataLoader``, ``SidarAugment``, the Ray batches)."""
    batch = {}
    for key in samples[0]:
        values = [s[key] for s in samples]
        if isinstance(values[0], torch.Tensor):
            batch[key] = torch.stack(values)
        elif isinstance(values[0], str):
            batch[key] = values
        else:
            batch[key] = torch.tensor(values, dtype=torch.int64 if isinstance(values[0], int) else torch.float64)
    return batch
