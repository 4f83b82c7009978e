"""Contact sheets: samples laid out as one picture for a quick look."""

from __future__ import annotations

from typing import Any, Sequence

import torch
import torch.nn.functional as F

__all__ = ["contact_sheet"]


def contact_sheet(samples: Sequence[dict[str, Any]], thumb_width: int = 256, gap: int = 4) -> torch.Tensor:
    """Lay out samples, two rows each: ``label, view 0 .. V-1`` above ``-, mask 0 .. V-1``.

    Args:
        samples: sample dicts (:data:`sidar_torch.sample.KEYS`; ``label``, ``images`` and ``masks``
            are shown), all of one size and ``V``.
        thumb_width: width of each tile in pixels (height keeps the aspect ratio).
        gap: white space between tiles, pixels.

    Returns:
        ``(3, rows * (h + gap), (V + 1) * (w + gap))`` uint8 tensor (channels first).
    """
    rows = []
    for s in samples:
        h, w = s["label"].shape[-2:]
        size = (max(1, round(h * thumb_width / w)), thumb_width)
        views = torch.cat([s["label"][None], s["images"]])
        masks = torch.cat([torch.zeros_like(s["label"][None]), s["masks"].expand(-1, 3, -1, -1)])
        for tiles in (views, masks):
            tiles = F.interpolate(tiles, size=size, mode="bilinear", antialias=True, align_corners=False)
            tiles = F.pad(tiles, (0, gap, 0, gap), value=1.0)
            rows.append(torch.cat(list(tiles), dim=2))
    return (torch.cat(rows, dim=1).clamp(0, 1) * 255).round().to(torch.uint8)
