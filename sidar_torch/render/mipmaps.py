"""The painting texture's mipmap levels, computed on the CPU as llvmpipe's ``glGenerateMipmap`` computes them.

llvmpipe (Mesa 22.3) makes each level by a linear blit of the level above it. Along a side of ``n`` texels
that becomes ``m = max(n // 2, 1)``, texel ``i`` samples the larger level at ``u = (i + 1/2) n / m - 1/2``
(texel centres, clamped to the edge) with the fraction of ``u`` as an 8-bit weight, ``w = round(256 frac)``,
and each blend rounded, ``(a (256 - w) + b w + 128) >> 8``: first along x, then along y. :func:`mip_levels`
does the same integer arithmetic, so it gives llvmpipe's bytes wherever llvmpipe's float32 coordinates
cannot round a weight the other way (:func:`exact_on_cpu`: no weight of the texture's odd sides within
float32's reach of a half; an even side is halved at weight 128 exactly). ``tests/render/test_mipmaps.py``
compares every level with ``glGenerateMipmap``'s for random textures of such sizes. Elsewhere (some odd sides
of about 200 texels or more) llvmpipe rounds near-half weights by float32 steps this does not copy, and the
renderer generates those textures' levels in GL.

Why not ``glGenerateMipmap``: llvmpipe compiles its blit shader in every new process at the first painting
(about 60 ms for a 384 x 512 painting, 44 ms more for another size's; Mesa's disk cache does not keep it),
which each DataLoader worker paid in its first sample. Here a refill of a 384 x 512 painting's levels
costs about as much as the blit did.
"""

from __future__ import annotations

import functools

import numpy as np

__all__ = ["FLOAT32_SLACK", "exact_on_cpu", "mip_levels"]

FLOAT32_SLACK = 2 * 4 * 256 * 2.0 ** -24
"""How far llvmpipe's float32 steps may move a weight (in 1/256 units), per texel of the side: four
roundings of a coordinate near ``n`` move it by at most ``4 * 256 * n * 2^-24``; twice that is kept clear."""


def exact_on_cpu(size: tuple[int, int]) -> bool:
    """Whether :func:`mip_levels` of a ``size (H, W)`` texture is llvmpipe's, byte for byte: no weight of an
    odd side's halving lies within :data:`FLOAT32_SLACK` of a tie (an even side's weights are 128 exactly)."""
    for n in size:
        while n > 1:
            if n % 2 and _tie_distance(n) <= FLOAT32_SLACK * n:
                return False
            n //= 2
    return True


@functools.lru_cache(maxsize=256)
def _tie_distance(n: int) -> float:
    """The least distance of a weight of an odd side ``n``'s halving to a tie (``k + 1/2``), in 1/256 units,
    exactly: texel ``i``'s weight is ``256 frac(u_i) = 128 r / m`` with the integer
    ``r = ((2 i + 1) n - m) mod 2 m``, so its distance is ``|(256 r mod 2 m) - m| / (2 m)``."""
    m = max(n // 2, 1)
    r = ((2 * np.arange(m, dtype=np.int64) + 1) * n - m) % (2 * m)
    return float(np.abs((256 * r) % (2 * m) - m).min() / (2 * m))


@functools.lru_cache(maxsize=64)
def _taps(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For a side of ``n`` texels halved (see the module docstring): each smaller texel's two taps ``(m,)``
    int64 and the 8-bit weight of the second ``(m,)`` int32 (read-only, shared)."""
    m = max(n // 2, 1)
    u = (np.arange(m) + 0.5) * (n / m) - 0.5
    first = np.floor(u)
    weight = np.floor((u - first) * 256 + 0.5).astype(np.int32)  # round half up, as llvmpipe's weights
    first = first.astype(np.int64)
    taps = (np.clip(first, 0, n - 1), np.minimum(first + 1, n - 1), weight)
    for array in taps:
        array.flags.writeable = False
    return taps


def _halve(levels: np.ndarray, axis: int) -> np.ndarray:
    """``levels`` (int16 levels 0-255) with side ``axis`` halved as llvmpipe's blit halves it."""
    n = levels.shape[axis]
    if n % 2 == 0:  # taps 2i and 2i + 1 at weight 128: (a 128 + b 128 + 128) >> 8 = (a + b + 1) >> 1
        even = [slice(None)] * levels.ndim
        odd = list(even)
        even[axis], odd[axis] = slice(0, None, 2), slice(1, None, 2)
        out = levels[tuple(even)] + levels[tuple(odd)]
        out += 1
        out >>= 1
        return out
    first, second, weight = _taps(n)
    shape = [1] * levels.ndim
    shape[axis] = -1
    weight = weight.reshape(shape)
    wide = levels.astype(np.int32)  # a (256 - w) + b w reaches 65280
    return ((wide.take(first, axis) * (256 - weight) + wide.take(second, axis) * weight + 128) >> 8).astype(np.int16)


def mip_levels(texels: np.ndarray) -> list[np.ndarray]:
    """Every mipmap level of ``texels`` after the first, as llvmpipe's ``glGenerateMipmap`` makes them
    (byte for byte where :func:`exact_on_cpu`). NumPy integer arithmetic: about 1 ms for a 384 x 512 RGB
    texture on one core.

    Args:
        texels: ``(H, W, C)`` uint8, level 0 as GL holds it (row 0 the texture's first row, ``t = 0``).

    Returns:
        Levels 1, 2, ... down to ``1 x 1``: each ``(max(h // 2, 1), max(w // 2, 1), C)`` uint8, contiguous.

    Raises:
        ValueError: ``texels`` is not ``(H, W, C)`` uint8.
    """
    if texels.ndim != 3 or texels.dtype != np.uint8:
        raise ValueError(f"texels: expected (H, W, C) uint8, got {texels.shape} {texels.dtype}")
    levels, out = texels.astype(np.int16), []
    while levels.shape[0] > 1 or levels.shape[1] > 1:
        levels = _halve(_halve(levels, 1), 0)  # x first, then y
        out.append(levels.astype(np.uint8))
    return out
