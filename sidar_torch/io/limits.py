"""What an export may hold, checked before anything is read: the recorded sizes against the package's
own bounds (the config's: :data:`sidar_torch.config.MAX_GL_SIZE`, :data:`~sidar_torch.config.MAX_VIEWS`,
:data:`~sidar_torch.config.MAX_SAMPLE_BYTES`), and the most bytes a sequence's file may have.

A manifest only says what the files should hold; the reader takes each size from the files
themselves (a PNG's header, ``cameras.json``'s cameras, a ``.npy`` header) and compares it with the
recorded one. With the recorded sizes bounded here, no file can make the reader allocate more
than a sample the package could have rendered.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping

from ..config import MAX_SAMPLE_BYTES, SidarConfig
from ..config.memory import output_bytes
from ..config.validation import check_field

__all__ = ["check_recorded_sizes", "entry_size_limit"]


def check_recorded_sizes(config: Mapping[str, Any], where: Path) -> None:
    """Check a recorded config's ``image_size`` and ``n_views`` (an ``export.json``'s, or inferred
    from a folder's files) as ``SidarConfig`` checks them: each within its field's bounds, and a
    sample's views, masks and optional outputs within :data:`~sidar_torch.config.MAX_SAMPLE_BYTES`
    by :func:`sidar_torch.config.memory.output_bytes` (a lower bound of what any config with these
    fields needs, so no export the package wrote is refused).

    Raises:
        ValueError: naming ``where`` and the field(s).
    """
    for name in ("image_size", "n_views"):
        try:
            check_field(SidarConfig.__dataclass_fields__[name], config.get(name))
        except ValueError as error:
            raise ValueError(f"{str(where)!r}: {error}") from None
    (height, width), views = config["image_size"], config["n_views"]
    need = output_bytes((height, width), views, config)
    if need > MAX_SAMPLE_BYTES:
        raise ValueError(f"{str(where)!r}: config fields 'image_size' and 'n_views': a sample of {views} views of "
                         f"{height} x {width} (H x W) pixels needs at least {need / 2**30:.3g} GiB "
                         f"(sidar_torch.config.memory.output_bytes), more than the {MAX_SAMPLE_BYTES / 2**30:g} GiB "
                         f"a sample may use: no sidar_torch export holds one")


JSON_BYTES_PER_VIEW = 4096
"""Most bytes per view of a sequence's ``.json`` file (``cameras.json``: about 650 to 920 bytes per
view, ``K``, ``R`` and ``t`` at full float64 precision). Parsed JSON takes up to about 9 times its bytes
in Python objects (a list of floats written ``0.5,``: 9.1 MB for 1 MB, tracemalloc's peak), so its
own limit keeps that small where a PNG's would not."""


def entry_size_limit(config: Mapping[str, Any], name: str = "") -> int:
    """Most bytes file ``name`` of a sequence rendered with ``config`` can hold, with a wide margin.

    A ``.json`` file (``cameras.json``): 64 KiB plus :data:`JSON_BYTES_PER_VIEW` per view. Any
    other: four times a view's raw RGB pixels (a PNG adds a few bytes per row and per 32 kB), plus
    128 bytes per pair of views (``homographies.npy`` holds 72), plus 1 MiB (headers).
    """
    height, width = config["image_size"]
    if name.endswith(".json"):
        return 2**16 + JSON_BYTES_PER_VIEW * config["n_views"]
    return 4 * height * width * 3 + 128 * config["n_views"] ** 2 + 2**20
