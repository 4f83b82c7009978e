"""Realism report: statistics of our views against the paper's Blender renders of the same paintings.

Reads the sequences the paper's own generator made (``--anchors DIR``: one folder per sequence with
``0.png .. 5.png`` Cycles views, ``J-m.png`` masks, ``gt.png`` label, ``H_0_J.mat`` homographies and
the ``source.png`` painting), renders ``--samples`` sequences of each ``--config`` preset with those
paintings as the source (painting ``index % len``, the anchors' image size), and prints one markdown
table per preset. Every row is a *per-painting mean*: each sequence's value (the mean over its views or
pairs, or its one figure), averaged over the sequences of each painting, then over the paintings (the
anchors are one sequence per painting; ours take painting ``index % len``), with a 90 % interval:
Student's t over the sequences' values, and for a fraction (of views, of pairs) also Clopper and
Pearson's exact binomial interval of the pooled count (:func:`per_painting`). A row passes ("within:
yes") when our mean lies inside Blender's interval; whether the two intervals overlap is printed
beside it but is not a pass (:func:`verdict`), and nothing passes by a tolerance on the ratio.

    python -m benchmarks.realism --anchors DIR --config paper_misaligned misaligned aligned --samples 12
    python -m benchmarks.realism --anchors DIR --config paper_misaligned --set plane_metallic=[0,1]

Definitions (every threshold is a named constant below):

* *painting pixels*: mask 0 (the painting visible); Blender's antialiased masks are cut at 128.
* *painting region* of view ``j``: pixels whose centre the homography ``H[j, 0]`` sends inside the
  label's frame, shrunk by :data:`REGION_MARGIN` pixels; the occluders' part of a mask is the mask
  within this region (outside it the masks are 1 for the background, with or without an occluder).
* *luma*: Rec. 709 luma of the 8-bit sRGB values (0..255); *luminance*: the same weights on linear
  light (0..1), used wherever light is compared as a ratio.
* *cast shadow* (ours, exact): a painting pixel whose luminance is less than :data:`SHADOW_RATIO`
  times its luminance in the render of the same scene with ``shadows=False`` (same scene, same
  draws: only the renderer's ``shadows`` setting differs), among pixels at least :data:`MIN_LIT` bright
  there. (Blender's and ours, estimated): the label warped into the view is the painting's albedo
  there; the shading ratio ``view / albedo`` (luminances, both blurred by :data:`SMOOTH_SIGMA` px) is
  the light, and a cast shadow is a hole in it: :func:`filled_light` fills each dark region that lit
  pixels surround to its rim's level (greyscale hole filling; the dark parts of a spot's pool or of a
  metallic painting reach the painting's edge and are not holes); a pixel is in shadow when its light
  is below :data:`SHADOW_RATIO` times that level. Pixels blown out (luma >= ``WHITE``) or with a dark
  albedo (below :data:`MIN_ALBEDO`) are not judged. Shadows cut by the painting's or the image's edge
  are missed, so the estimate is compared only with the estimate; ours by both methods shows how far
  the estimate is from the truth, and on the ``shadows=False`` twin what it finds where there is
  nothing (``docs/realism.md``).
* *clipped pixels still coloured*: of a view's painting pixels with a channel at ``exposure.CLIPPED``
  or more, the fraction with another channel below ``exposure.STILL_COLOURED`` (how over-exposure is
  clipped: per channel keeps colour, a spill into white does not).
* *occluder coverage*: fraction of the painting region covered by the mask.
* *occluders per view*: ours from the scene: occluders whose bounding sphere, projected into the view,
  overlaps the painting region; ours and Blender's from the mask: 8-connected components of the mask
  within the painting region of at least :data:`MIN_COMPONENT` pixels.
* *detail gain* (:func:`detail_gain`): the least-squares slope of the view's Laplacian (linear
  luminance, divided by the view's light) on the Laplacian of the painting warped into the view, over
  painting pixels :data:`DETAIL_MARGIN` px away from occluders, clipped or near-black pixels and the
  region's edge: view 0; views 1-5; and views 1-5 by the smallest local scale of each pixel
  (:func:`local_scale`) below and from :data:`MINIFIED`. The painting is ours' exact label and the
  paper's ``source.png`` (its ``gt.png`` is an EEVEE render, itself blurred).
* *dark area* (:func:`dark_area`): fraction of a view's visible painting pixels whose light (view over
  albedo luminance, as the shadow estimate smooths them) is below :data:`DARK_LIGHT` of the view's
  median light.
* *edge sharpness*: at each pair of neighbouring pixels across the mask's edge inside the painting
  region (rows and columns), the largest one-pixel luma step divided by the whole luma step across
  :data:`EDGE_REACH` pixels each side, where that whole step is at least :data:`EDGE_CONTRAST` levels;
  the view's figure is the median. 1 is a hard, aliased step; an edge antialiased over two pixels
  gives about 0.5.
* *occluder saturation*: the median HSV saturation ``(max - min) / max`` of the 8-bit RGB values of
  the mask's pixels within the painting region (views with at least :data:`MIN_OCCLUDER_PIXELS`).
* *view 0's blur*: ``benchmarks.blur.view_blur`` of view 0 against the label (Blender's: against
  ``source.png``, ``benchmarks.blur.anchor_view0_blur``), one figure per sequence.
* *matcher rows*: ``benchmarks.matcher``: SIFT keypoints on the painting per view, ratio-test
  matches per pair of views, the fraction of pairs whose RANSAC homography is within
  ``matcher.SUCCESS_PX`` of the true one (mean corner distance) and the median error of those pairs;
  their intervals resample whole sequences (a sequence's views share a painting and its pairs share
  views).
* *diagnostics* (:data:`DIAGNOSTICS`, the table's last rows): the exact cast-shadow fraction and darkness
  of ours and the estimator's false shadows on our ``shadows=False`` twins. Blender has no counterpart
  (only its estimate can be measured), so they get no verdict: the exact rows show their ratio to our
  own estimate, the false-shadow row what it should read (near 0).
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path
from typing import Any, Callable

import numpy as np
from scipy import ndimage, special

from benchmarks.common import parse_set
from benchmarks.exposure import BLACK, CLIPPED, LUMA, STILL_COLOURED, WHITE, view_exposure
from benchmarks.images import (anchor_sequences, inverse_map, luminance, painting_region, read_rgb, srgb_to_linear,
                               to_uint8, warp_label)
from benchmarks.matcher import SUCCESS_PX, MatcherStats, matcher_stats

DARK_MEDIAN = 50
"""A view is *dark* when the median luma of its painting pixels is below this."""

BLOWN_VIEW = 0.10
"""A view is *blown out* when more than this fraction of its painting pixels is near-white."""

BLACK_VIEW = 0.30
"""A view is *mostly black* when more than this fraction of its painting pixels is near-black."""

SHADOW_RATIO = 0.5
"""A painting pixel is in cast shadow when its light is less than this fraction of the unshadowed light."""

DARKENED = 0.9
"""A painting pixel counts towards shadow darkness when its light is below this fraction of the unshadowed
light (umbrae, penumbrae and faint shadows alike)."""

MIN_LIT = 0.02
"""Least unshadowed luminance (linear, 0..1) at which a pixel's darkening is judged."""

MIN_ALBEDO = 0.02
"""Least label luminance (linear) at which the estimator judges a pixel (a ratio to black is noise)."""

SMOOTH_SIGMA = 3.0
"""Gaussian blur (pixels) of the view's and the warped label's luminance before their ratio is taken:
the warped label is a resampling of the painting, not the renderer's own texture filtering."""

HOLE_STEP = float(np.log(2) / 8)
"""Step (natural log of light) of the levels at which :func:`filled_light` follows paths to the
painting's edge: its fill level is exact to this (9 %)."""

MIN_JUDGED = 100
"""Least judged pixels for a view to have an estimated cast-shadow fraction."""

MIN_COMPONENT = 30
"""Least pixels of a mask component counted as an occluder (drops slivers at the region's edge)."""

EDGE_REACH = 2
"""Pixels each side of a mask edge over which the luma step is measured."""

EDGE_CONTRAST = 24
"""Least luma step (0..255) across a mask edge for it to be measured."""

MIN_EDGES = 10
"""Least measured edge pixels for a view to have an edge-sharpness figure."""

MIN_OCCLUDER_PIXELS = 100
"""Least occluder pixels within the painting region for a view to have an occluder-saturation figure."""


# --- statistics (pure numpy) -------------------------------------------------------------------


def luma(views: np.ndarray) -> np.ndarray:
    """Rec. 709 luma ``(...)`` in 0..255 of 8-bit sRGB ``(..., 3)``."""
    return np.asarray(views, np.float64) @ LUMA


def exact_light_ratio(lit: np.ndarray, unshadowed: np.ndarray, painting: np.ndarray) -> np.ndarray:
    """Light ratio (shadowed over unshadowed luminance) of each judged painting pixel, ``(N,)``, from a
    render and its ``shadows=False`` twin.

    Args:
        lit, unshadowed: ``(H, W, 3)`` uint8 sRGB renders of the same scene with and without shadows.
        painting: ``(H, W)`` bool, True where the painting is visible (mask 0).

    Pixels darker than :data:`MIN_LIT` in the twin are not judged and count as 1 (unshadowed).
    """
    y_lit, y_free = luminance(lit)[painting], luminance(unshadowed)[painting]
    judged = y_free >= MIN_LIT
    return np.where(judged, y_lit / np.where(judged, y_free, 1.0), 1.0)


def shadow_fraction(ratio: np.ndarray | None) -> float:
    """Fraction of pixels whose light ratio ``(N,)`` is below :data:`SHADOW_RATIO` (NaN for None or none)."""
    return float((ratio < SHADOW_RATIO).mean()) if ratio is not None and ratio.size else float("nan")


def shadow_darkness(ratio: np.ndarray | None) -> float:
    """Median light ratio of the pixels darkened below :data:`DARKENED` (NaN with fewer than
    :data:`MIN_JUDGED` such pixels): how dark a view's shadows are, not how many there are."""
    if ratio is None:
        return float("nan")
    dark = ratio[ratio < DARKENED]
    return float(np.median(dark)) if dark.size >= MIN_JUDGED else float("nan")


def smoothed(values: np.ndarray, valid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Gaussian mean (sigma :data:`SMOOTH_SIGMA` px) of ``values (H, W)`` over ``valid`` pixels, and the
    weight of valid pixels in it (0..1)."""
    weight = ndimage.gaussian_filter(valid.astype(np.float64), SMOOTH_SIGMA)
    total = ndimage.gaussian_filter(np.where(valid, values, 0.0), SMOOTH_SIGMA)
    return total / np.maximum(weight, 1e-9), weight


def filled_light(log_light: np.ndarray, inside: np.ndarray) -> np.ndarray:
    """The light level each pixel's dark hole is filled to: for each pixel of ``inside``, the least level
    ``t`` (a multiple of :data:`HOLE_STEP` above the least value) such that a 4-connected path of
    pixels at or below ``t`` leads from it out of ``inside`` (greyscale hole filling); ``+inf`` off it.

    Args:
        log_light: ``(H, W)`` float64, the log light level of every pixel of ``inside``.
        inside: ``(H, W)`` bool, the painting region; the pixels off it, the image's border
            included, are the outside every path ends in.

    Returns:
        ``(H, W)`` float64, at least ``log_light`` on ``inside``. A shadow, a hole in the light that
        lit pixels surround, is filled to its surroundings' level; the dark part of a spot's pool or
        of a metallic painting reaches the painting's edge through dark pixels, and stays as it is.
    """
    filled = np.full(log_light.shape, np.inf)
    frame = np.zeros(log_light.shape, bool)
    frame[[0, -1], :] = frame[:, [0, -1]] = True
    outside = ~inside | frame
    todo = inside & ~outside
    filled[inside & frame] = log_light[inside & frame]
    values = log_light[todo]
    for level in np.arange(values.min(), values.max() + HOLE_STEP, HOLE_STEP) if values.size else []:
        labels, _ = ndimage.label(outside | (inside & (log_light <= level)))
        reached = todo & np.isin(labels, np.unique(labels[outside]))
        filled[reached] = level
        todo &= ~reached
        if not todo.any():
            break
    return np.where(inside, np.maximum(filled, log_light), np.inf)


def estimated_light_ratio(view: np.ndarray, albedo: np.ndarray, painting: np.ndarray,
                          region: np.ndarray) -> np.ndarray | None:
    """Light ratio (light over the level its hole is filled to) of each judged painting pixel, ``(N,)``,
    estimated from one render and the label.

    The shading ratio ``view / albedo`` (luminances, each smoothed by :data:`SMOOTH_SIGMA` px) is the
    light; the unjudged pixels of the region (occluders, blown-out or dark-albedo pixels) take their
    nearest judged pixel's, and :func:`filled_light` fills its dark holes. A cast shadow is such a hole:
    the pixels around it are lit. Shading does not make holes (a spot's pool is a bright patch in the
    dark, a metallic painting dark with bright highlights), so on our ``shadows=False`` twins this reads
    near 0; a shadow that the painting's or the image's edge cuts is not a hole, and is missed
    (``docs/realism.md``).

    Args:
        view: ``(H, W, 3)`` uint8 sRGB render.
        albedo: ``(H, W, 3)`` float 0..255 sRGB, the label warped into the view (NaN off it).
        painting: ``(H, W)`` bool, True where the painting is visible (mask 0).
        region: ``(H, W)`` bool, the painting region (:func:`painting_region`).

    Returns:
        the ratios, None when fewer than :data:`MIN_JUDGED` pixels can be judged.
    """
    valid = painting & region & np.isfinite(albedo).all(-1) & (luma(view) < WHITE)
    lit, weight = smoothed(luminance(view), valid)
    reflectance, _ = smoothed(srgb_to_linear(np.nan_to_num(albedo, nan=0.0).round()) @ LUMA, valid)
    judged = valid & (weight > 0.5) & (reflectance >= MIN_ALBEDO) & (lit > 0)
    if judged.sum() < MIN_JUDGED:
        return None
    log_ratio = np.zeros(judged.shape)
    log_ratio[judged] = np.log(lit[judged] / reflectance[judged])
    nearest = ndimage.distance_transform_edt(~judged, return_distances=False, return_indices=True)
    log_ratio = log_ratio[tuple(nearest)]
    log_ratio[region & painting & (luma(view) >= WHITE)] = log_ratio[judged].max()  # blown out: lit
    return np.exp(log_ratio[judged] - filled_light(log_ratio, region)[judged])


def occluder_coverage(mask: np.ndarray, region: np.ndarray) -> float:
    """Fraction of the painting region ``(H, W)`` bool covered by ``mask`` ``(H, W)`` bool (True: hidden)."""
    return float(mask[region].mean()) if region.any() else float("nan")


def occluder_components(mask: np.ndarray, region: np.ndarray, min_pixels: int = MIN_COMPONENT) -> int:
    """8-connected components of ``mask & region`` with at least ``min_pixels`` pixels."""
    labels, n = ndimage.label(mask & region, structure=np.ones((3, 3), bool))
    sizes = np.bincount(labels.ravel(), minlength=n + 1)[1:]
    return int((sizes >= min_pixels).sum())


def edge_sharpness(view: np.ndarray, mask: np.ndarray, region: np.ndarray) -> float:
    """Median over the mask's edge pixels of the largest one-pixel luma step over the whole step
    (see the module docstring); NaN with fewer than :data:`MIN_EDGES` measured edges.

    Args:
        view: ``(H, W, 3)`` uint8 sRGB; mask, region: ``(H, W)`` bool.
    """
    values = []
    lum = luma(view)
    for image, hidden, inside in ((lum, mask, region), (lum.T, mask.T, region.T)):
        n = image.shape[1]
        reach = EDGE_REACH
        # an edge between columns x and x + 1; the profile runs from x - reach + 1 to x + reach
        ys, xs = np.nonzero(hidden[:, :-1] != hidden[:, 1:])
        keep = (xs - reach + 1 >= 0) & (xs + reach < n)
        ys, xs = ys[keep], xs[keep]
        offsets = np.arange(-reach + 1, reach + 1)
        cols = xs[:, None] + offsets[None, :]
        rows = np.broadcast_to(ys[:, None], cols.shape)
        whole_region = inside[rows, cols].all(axis=1)
        profile = image[rows, cols][whole_region]
        total = np.abs(profile[:, -1] - profile[:, 0])
        largest = np.abs(np.diff(profile, axis=1)).max(axis=1)
        measured = total >= EDGE_CONTRAST
        values.append(np.minimum(largest[measured] / total[measured], 1.0))
    values = np.concatenate(values)
    return float(np.median(values)) if values.size >= MIN_EDGES else float("nan")


def occluder_saturation(view: np.ndarray, mask: np.ndarray, region: np.ndarray) -> float:
    """Median HSV saturation ``(max - min) / max`` (0 for black) of the view's pixels where ``mask``
    covers ``region``; NaN with fewer than :data:`MIN_OCCLUDER_PIXELS` such pixels.

    Args:
        view: ``(H, W, 3)`` uint8 RGB; mask, region: ``(H, W)`` bool.
    """
    pixels = view[mask & region].astype(np.float64)
    if len(pixels) < MIN_OCCLUDER_PIXELS:
        return float("nan")
    top, bottom = pixels.max(axis=1), pixels.min(axis=1)
    return float(np.median(np.where(top > 0, (top - bottom) / np.maximum(top, 1), 0.0)))


# --- detail and dark area ----------------------------------------------------------------------


MINIFIED = 0.5
"""Smallest local scale (view pixels per painting pixel, along the direction the view shrinks the
painting most) below which a pixel counts as *minified* in the detail-gain rows."""

DETAIL_MARGIN = 3
"""Pixels around an occluder's or the painting region's edge, and around a clipped (a channel at
``exposure.CLIPPED``) or near-black (luma <= ``exposure.BLACK``) pixel, where the detail gain is not
judged (the Laplacian there holds the edge or the clipping, not the painting)."""

MIN_DETAIL_PIXELS = 500
"""Least judged pixels (of a view, or of one of its scale bins) for a detail-gain figure."""

DARK_LIGHT = 0.25
"""A visible painting pixel is in the *dark area* when its light is below this fraction of the view's
median light."""


def local_scale(H: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """``(H, W)`` float64: at each pixel of a view, the smallest local scale of the map from the painting
    (view 0's frame) into the view, in view pixels per painting pixel: the smaller singular value of
    its Jacobian, the scale along the direction it shrinks the painting most (NaN where the ray misses).

    Args:
        H: ``(3, 3)`` homography from view 0 (the painting's frame) to the view, Kornia convention.
        size: ``(H, W)`` of the view.
    """
    x, y = inverse_map(H, size)
    G = np.linalg.inv(H)
    h, w = size
    v, u = np.mgrid[0:h, 0:w].astype(np.float64)
    d = G[2, 0] * u + G[2, 1] * v + G[2, 2]
    # d(x, y) / d(u, v) of the inverse map x = (G0 . p) / (G2 . p), y = (G1 . p) / (G2 . p)
    J = np.stack([np.stack([G[0, 0] - x * G[2, 0], G[0, 1] - x * G[2, 1]], -1),
                  np.stack([G[1, 0] - y * G[2, 0], G[1, 1] - y * G[2, 1]], -1)], -2) / d[..., None, None]
    finite = np.isfinite(J).all(axis=(-1, -2))
    largest = np.full(size, np.nan)
    largest[finite] = np.linalg.svd(J[finite], compute_uv=False)[:, 0]  # painting pixels per view pixel
    return 1.0 / largest


def warp_plane(image: np.ndarray, H: np.ndarray) -> np.ndarray:
    """One channel ``(H, W)`` float64 in view 0's frame seen in a view through ``H`` (view 0 -> view,
    Kornia convention), by cubic spline interpolation (which passes through the pixels' values and,
    unlike bilinear, does not blur at half-pixel offsets); NaN where the pixel's centre falls off it."""
    x, y = inverse_map(H, image.shape)
    h, w = image.shape
    with np.errstate(invalid="ignore"):
        inside = (x >= -0.5) & (x <= w - 0.5) & (y >= -0.5) & (y <= h - 0.5)
    coords = np.stack([np.where(inside, y, 0.0), np.where(inside, x, 0.0)])
    out = ndimage.map_coordinates(image, coords, order=3, mode="nearest")
    return np.where(inside, out, np.nan)


def detail_gain(view: np.ndarray, source: np.ndarray, H: np.ndarray, visible: np.ndarray,
                region: np.ndarray) -> tuple[float, float, float]:
    """How much of the painting's fine detail a view shows: the least-squares slope (through 0) of the
    view's Laplacian on the Laplacian of the painting warped into the view.

    Both in linear luminance and in the view's pixels: the painting is warped into the view through
    ``H`` (:func:`warp_plane`, point-sampled: what an unfiltered view of it would show), and the view's
    Laplacian is divided by the view's light there (its luminance over the warped painting's, both
    smoothed by :data:`SMOOTH_SIGMA` px), so the lights' level does not count. The slope of ``y`` on
    ``x`` is unbiased by noise in ``y``: the view's noise (Cycles' sampling and denoiser, 8-bit steps)
    adds scatter but not slope, where a ratio of Laplacian energies would count it as detail. A view
    that is the painting warped and unblurred gains 1, at any scale; any blur, a pixel filter or a
    texture filter, less. A minified view cannot hold the painting's finest detail without aliasing, so
    a renderer's filtering shows there most: the figure is also given by scale (:func:`local_scale`,
    :data:`MINIFIED`).

    Args:
        view: ``(H, W, 3)`` uint8 sRGB render.
        source: ``(H, W, 3)`` uint8 sRGB, the painting in view 0's frame (ours: the label; the paper's:
            ``source.png``, which fills its view 0 exactly).
        H: ``(3, 3)`` homography from view 0 to this view.
        visible: ``(H, W)`` bool, True where the painting is visible (mask 0).
        region: ``(H, W)`` bool, the painting region (:func:`painting_region`).

    Returns:
        the gain over all judged pixels, over those whose smallest local scale is below
        :data:`MINIFIED`, and over the rest (NaN where fewer than :data:`MIN_DETAIL_PIXELS` are judged).
    """
    albedo = warp_plane(luminance(source), H)
    x = ndimage.laplace(albedo)  # NaN next to the painting's edge
    lum, lum8 = luminance(view), luma(view)
    usable = visible & region & np.isfinite(albedo) & (view.max(axis=-1) < CLIPPED) & (lum8 > BLACK)
    judged = ndimage.binary_erosion(usable, iterations=DETAIL_MARGIN, border_value=0) & np.isfinite(x)
    lit, weight = smoothed(lum, usable)
    reflectance, _ = smoothed(np.nan_to_num(albedo, nan=0.0), usable)
    judged &= (weight > 0.5) & (reflectance >= MIN_ALBEDO) & (lit > 0)
    light = np.where(judged, lit / np.where(judged, reflectance, 1.0), 1.0)
    y = ndimage.laplace(lum) / light
    scale = local_scale(H, view.shape[:2])
    gains = []
    for pixels in (judged, judged & (scale < MINIFIED), judged & (scale >= MINIFIED)):
        xs, ys = x[pixels], y[pixels]
        energy = float(xs @ xs)
        gains.append(float(xs @ ys) / energy if pixels.sum() >= MIN_DETAIL_PIXELS and energy > 0 else float("nan"))
    return gains[0], gains[1], gains[2]


def dark_area(view: np.ndarray, albedo: np.ndarray, visible: np.ndarray, region: np.ndarray) -> float:
    """Fraction of a view's visible painting pixels whose light is below :data:`DARK_LIGHT` times the
    view's median light (NaN with fewer than :data:`MIN_JUDGED` judged pixels).

    The light is the view's luminance over the painting's albedo there (the label warped into the view),
    each smoothed by :data:`SMOOTH_SIGMA` px over the visible painting, as the shadow estimate takes it;
    pixels of dark albedo (below :data:`MIN_ALBEDO`) are not judged, blown-out ones are (they are lit).
    Light falloff (a spot's pool fading to black, a corner the lights leave dark) and cast shadows both
    count: it is how much of the painting a view leaves very dark, whatever the cause.

    Args:
        view: ``(H, W, 3)`` uint8 sRGB render; albedo: ``(H, W, 3)`` float 0..255 sRGB, the label warped
            into the view (NaN off it); visible, region: ``(H, W)`` bool (mask 0; the painting region).
    """
    valid = visible & region & np.isfinite(albedo).all(-1)
    lit, weight = smoothed(luminance(view), valid)
    reflectance, _ = smoothed(srgb_to_linear(np.nan_to_num(albedo, nan=0.0).round()) @ LUMA, valid)
    judged = valid & (weight > 0.5) & (reflectance >= MIN_ALBEDO)
    if judged.sum() < MIN_JUDGED:
        return float("nan")
    light = lit[judged] / reflectance[judged]
    return float((light < DARK_LIGHT * np.median(light)).mean())


@dataclasses.dataclass
class ViewStats:
    """Per-view statistics of a set of views (each array ``(N,)``; NaN where a view has no figure).
    ``detail``, ``detail_minified`` and ``detail_resolved`` are :func:`detail_gain`'s three figures;
    ``view``, ``sequence`` and ``painting`` say which view of which sequence of which painting each is
    (ints as floats), so figures can be taken per painting."""

    median_luma: np.ndarray
    near_white: np.ndarray
    near_black: np.ndarray
    clipped_coloured: np.ndarray
    shadow_exact: np.ndarray
    shadow_estimated: np.ndarray
    shadow_estimated_twin: np.ndarray
    darkness_exact: np.ndarray
    darkness_estimated: np.ndarray
    coverage: np.ndarray
    occluders_scene: np.ndarray
    occluders_mask: np.ndarray
    sharpness: np.ndarray
    saturation: np.ndarray
    detail: np.ndarray
    detail_minified: np.ndarray
    detail_resolved: np.ndarray
    dark_area: np.ndarray
    view: np.ndarray
    sequence: np.ndarray
    painting: np.ndarray

    @staticmethod
    def concat(parts: list["ViewStats"]) -> "ViewStats":
        return ViewStats(*(np.concatenate([getattr(p, f.name) for p in parts]) for f in dataclasses.fields(ViewStats)))


def sequence_stats(views: np.ndarray, masks: np.ndarray, label: np.ndarray, H0: np.ndarray,
                   unshadowed: np.ndarray | None = None, occluders_scene: np.ndarray | None = None,
                   source: np.ndarray | None = None, sequence: int = 0, painting_index: int = 0) -> ViewStats:
    """Statistics of one sequence's ``V`` views.

    Args:
        views: ``(V, H, W, 3)`` uint8 sRGB; masks: ``(V, H, W)`` bool (True: painting not visible).
        label: ``(H, W, 3)`` uint8, the painting in view 0's frame.
        H0: ``(V, 3, 3)`` homographies from view 0 (the label's frame) to each view, Kornia convention.
        unshadowed: ``(V, H, W, 3)`` uint8 renders with ``shadows=False`` (ours only), else None.
        occluders_scene: ``(V,)`` occluders over the painting per view from the scene (ours only).
        source: ``(H, W, 3)`` uint8, the painting itself in view 0's frame, against which the detail gain
            is measured (the paper's ``source.png``: its label ``gt.png`` is an EEVEE render, itself
            blurred); None: ``label`` (ours, exact).
        sequence, painting_index: which sequence and which painting these views are (recorded per view).
    """
    exposure = view_exposure(views, masks)
    nan = np.full(len(views), np.nan)
    shadows = []  # per view: exact, estimated and twin's estimated fractions, exact and estimated darkness
    coverage, components, sharpness, saturation, detail, dark = [], [], [], [], [], []
    source = label if source is None else source
    for j, (view, mask) in enumerate(zip(views, masks)):
        region = painting_region(H0[j], view.shape[:2])
        painting = ~mask
        albedo = warp_label(label, H0[j])
        exact = None if unshadowed is None or not painting.any() else exact_light_ratio(view, unshadowed[j], painting)
        estimated = estimated_light_ratio(view, albedo, painting, region)
        twin = None if unshadowed is None else estimated_light_ratio(unshadowed[j], albedo, painting, region)
        shadows.append([shadow_fraction(exact), shadow_fraction(estimated), shadow_fraction(twin),
                        shadow_darkness(exact), shadow_darkness(estimated)])
        coverage.append(occluder_coverage(mask, region))
        components.append(occluder_components(mask, region))
        sharpness.append(edge_sharpness(view, mask, region))
        saturation.append(occluder_saturation(view, mask, region))
        detail.append(detail_gain(view, source, H0[j], painting, region))
        dark.append(dark_area(view, albedo, painting, region))
    return ViewStats(exposure.median, exposure.white, exposure.black, exposure.clipped_coloured, *np.array(shadows).T,
                     np.array(coverage), nan if occluders_scene is None else np.asarray(occluders_scene, float),
                     np.array(components, float), np.array(sharpness), np.array(saturation), *np.array(detail).T,
                     np.array(dark), np.arange(len(views), dtype=float), np.full(len(views), float(sequence)),
                     np.full(len(views), float(painting_index)))


@dataclasses.dataclass(frozen=True)
class SequenceStats:
    """Statistics of one whole sequence: ``blur``, view 0's effective blur in pixels
    (``benchmarks.blur.view_blur``; NaN when too little of the painting is judged), ``matcher``, and
    ``painting``, which painting it shows (the index of its source among the anchors')."""

    blur: float
    matcher: MatcherStats
    painting: int = 0


# --- the paper's sequences -----------------------------------------------------------------------


def paper_to_kornia(H: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """A homography in the paper's pixel convention (image edges at 0 and W - 1) in Kornia's (pixel
    centres at integers): ``S^-1 H S`` with ``S`` the map from Kornia's pixels to the paper's."""
    h, w = size
    S = np.array([[(w - 1) / w, 0, (w - 1) / (2 * w)], [0, (h - 1) / h, (h - 1) / (2 * h)], [0, 0, 1]])
    return np.linalg.inv(S) @ H @ S


def anchor_homographies(sequence: Path, count: int, size: tuple[int, int]) -> np.ndarray:
    """``(V, V, 3, 3)`` homographies between the ``count`` views of one of the paper generator's
    sequences in Kornia's convention: ``H_i_j.mat`` (``i < j``) converted by :func:`paper_to_kornia`,
    their inverses for ``i > j``, the identity for ``i = j``."""
    H = np.tile(np.eye(3), (count, count, 1, 1))
    for i in range(count):
        for j in range(i + 1, count):
            H[i, j] = paper_to_kornia(np.loadtxt(sequence / f"H_{i}_{j}.mat"), size)
            H[j, i] = np.linalg.inv(H[i, j])
    return H


def anchor_stats(sequence: Path, index: int = 0) -> tuple[ViewStats, SequenceStats]:
    """Statistics of one of the paper generator's sequences (views ``0.png``, ``1.png``, ...), the
    ``index``-th of the anchors: its painting is painting ``index`` (one painting per sequence)."""
    from benchmarks.blur import anchor_view0_blur  # blur.py imports this module

    count = len(list(sequence.glob("[0-9]*-m.png")))
    views = np.stack([read_rgb(sequence / f"{j}.png") for j in range(count)])
    masks = np.stack([read_rgb(sequence / f"{j}-m.png")[..., 0] >= 128 for j in range(count)])
    H = anchor_homographies(sequence, count, views.shape[1:3])
    return (sequence_stats(views, masks, read_rgb(sequence / "gt.png"), H[0], source=read_rgb(sequence / "source.png"),
                           sequence=index, painting_index=index),
            SequenceStats(anchor_view0_blur(sequence), matcher_stats(views, masks, H), index))


# --- ours ---------------------------------------------------------------------------------------


def occluders_over_painting(scene: Any, region: np.ndarray) -> int:
    """Occluders of one ``ViewScene`` whose bounding sphere, projected, overlaps ``region`` ``(H, W)``."""
    ys, xs = np.nonzero(region)
    count = 0
    for occluder in scene.occluders:
        centre = scene.camera.R @ occluder.position + scene.camera.t
        radius = float(np.linalg.norm(occluder.scale))
        if centre[2] <= radius:  # reaches behind the camera: count it if its centre is ahead
            count += int(centre[2] > 0)
            continue
        u, v, _ = scene.camera.K @ centre / centre[2]
        focal = max(scene.camera.K[0, 0], scene.camera.K[1, 1])
        reach = focal * radius / np.sqrt(centre[2] ** 2 - radius**2) + 1
        count += int(((xs - u) ** 2 + (ys - v) ** 2 <= reach**2).any())
    return count


def our_stats(config: Any, sources: list[Path], samples: int,
              seed: int) -> tuple[ViewStats, list[SequenceStats], float]:
    """Statistics of ``samples`` sequences of ``config`` with the anchors' paintings, and seconds spent."""
    from benchmarks.blur import view_blur  # blur.py imports this module
    from sidar_torch import SidarDataset
    from sidar_torch.sample import render_sample
    from sidar_torch.scene import sample_sequence

    dataset = SidarDataset(source=[str(p) for p in sources], config=config, seed=seed)
    free_config = dataset.config.replace(shadows=False)
    free_dataset = SidarDataset(source=[str(p) for p in sources], config=free_config, seed=seed)  # for its renderer
    parts, sequences, start = [], [], time.perf_counter()
    for index in range(samples):
        rng = dataset.generator(index)
        scene = sample_sequence(dataset.config, rng)
        free_scene = sample_sequence(free_config, dataset.generator(index))
        if free_scene != scene:
            raise RuntimeError(f"sample {index}: shadows=False drew a different scene")
        painting = dataset.source.painting(index % len(dataset.source), dataset.config.image_size)
        lit = render_sample(dataset.renderer(), scene, painting, dataset.config, index, rng=rng)
        free = render_sample(free_dataset.renderer(), free_scene, painting, free_config, index,
                             rng=dataset.generator(index))
        # ``mesh_detail: auto`` may pick a finer mesh for an occluder whose shadow is drawn, which moves
        # its silhouette by less than ``mesh_error_px``: a few edge pixels, never a different scene.
        changed = float((lit["masks"] != free["masks"]).float().mean())
        if changed > 1e-3:
            raise RuntimeError(f"sample {index}: shadows changed {changed:.2%} of the mask pixels")
        views, free_views = (to_uint8(s["images"]) for s in (lit, free))
        masks = lit["masks"][:, 0].numpy() > 0.5
        H = lit["homographies"].double().numpy()
        label = to_uint8(lit["label"][None])[0]
        regions = [painting_region(H[0, j], views.shape[1:3]) for j in range(len(views))]
        counted = [occluders_over_painting(v, r) for v, r in zip(scene.views, regions)]
        which = index % len(dataset.source)  # the painting, as the dataset picks it
        parts.append(sequence_stats(views, masks, label, H[0], free_views, np.array(counted), sequence=index,
                                    painting_index=which))
        sequences.append(SequenceStats(view_blur(views[0], masks[0], label, H[0, 0]), matcher_stats(views, masks, H),
                                       which))
    return ViewStats.concat(parts), sequences, time.perf_counter() - start


# --- the table ----------------------------------------------------------------------------------


CONFIDENCE = 0.90
"""Two-sided level of every interval in the table (5-95 %)."""


@dataclasses.dataclass(frozen=True)
class Figure:
    """One side's figure of a row of the table.

    Attributes:
        mean: the per-painting mean: each sequence's value (the mean of its views' or pairs' values, or
            its one figure; sequences with none are left out) averaged over the sequences of each
            painting, then over the paintings.
        interval: the :data:`CONFIDENCE` interval of ``mean`` (:func:`per_painting`).
        median: the median over every view (pair, or sequence) pooled, and for a fraction the pooled
            fraction; printed for reading only.
        sequences: how many sequences have a value.
    """

    mean: float
    interval: tuple[float, float]
    median: float
    sequences: int


def t_half_width(values: np.ndarray) -> float:
    """Half the width of Student's t :data:`CONFIDENCE` interval of the mean of ``values (n,)`` (NaN for
    ``n < 2``): ``t(n - 1) s / sqrt(n)``, with ``s`` the sample standard deviation."""
    n = len(values)
    if n < 2:
        return float("nan")
    return float(special.stdtrit(n - 1, 0.5 + CONFIDENCE / 2) * np.std(values, ddof=1) / np.sqrt(n))


def binomial_interval(count: int, total: int) -> tuple[float, float]:
    """Clopper and Pearson's exact 5-95 % interval of a fraction seen as ``count`` of ``total`` (``total`` >= 1)
    independent trials: the fractions at which seeing at least (at most) ``count`` has probability 5 %.
    Unlike an interval from the spread of what was seen, it is not a single point at 0 or at ``total``
    (0 of 36 views: 0 - 0.080)."""
    tail = (1 - CONFIDENCE) / 2
    low = 0.0 if count == 0 else float(special.betaincinv(count, total - count + 1, tail))
    high = 1.0 if count == total else float(special.betaincinv(count + 1, total - count, 1 - tail))
    return low, high


def per_painting(groups: list[np.ndarray], paintings: np.ndarray, reduce: Callable[[np.ndarray], float] = np.mean,
                 fraction: bool = False) -> Figure:
    """A row's figure from the items of each sequence.

    Args:
        groups: one ``(n_s,)`` array per sequence: its views' values, its pairs', or its one figure (NaN
            items are dropped; a sequence left with none has no value).
        paintings: ``(S,)`` the painting of each sequence.
        reduce: a sequence's value from its items (the mean; the median for the matched pairs' error).
        fraction: the items are flags (bool) and the row a fraction (of views, of pairs).

    The centre is the per-painting mean (:class:`Figure`). The interval is Student's t interval of the
    mean of the sequences' values, ``t(S - 1) s / sqrt(S)`` about that centre: the sequences are the
    independent draws (the paper's six references are six runs of its generator, one per painting; ours
    are seeded scenes), and t, not a bootstrap, because six values bootstrap to too narrow an interval
    (a bootstrap's percentiles of a mean of six are about ``sqrt(5/6)`` of the spread's and take no account
    of the spread's own uncertainty). It is clipped to what the values can take (at 0 when none is
    negative, at 1 for a fraction). A fraction's interval also holds Clopper and Pearson's exact interval
    of the pooled count (:func:`binomial_interval`), which does not shrink to a point when every
    sequence reads 0: 0 of 36 views is 0 - 0.080, what a rate of 2 % gives half the time.
    """
    items = [np.asarray(g, np.float64).ravel() for g in groups]
    items = [g[np.isfinite(g)] for g in items]
    values = np.array([reduce(g) if g.size else np.nan for g in items], np.float64)
    has = np.isfinite(values)
    pooled_items = np.concatenate(items) if items else np.zeros(0)
    if not has.any():
        return Figure(float("nan"), (float("nan"), float("nan")), float("nan"), 0)
    v, p = values[has], np.asarray(paintings)[has]
    mean = float(np.mean([v[p == k].mean() for k in np.unique(p)]))
    half = t_half_width(v)
    low, high = mean - half, mean + half
    if (v >= 0).all():
        low = max(low, 0.0)
    if fraction:
        high = min(high, 1.0)
        exact = binomial_interval(int(pooled_items.sum()), pooled_items.size)
        low, high = (exact if np.isnan(half) else (min(low, exact[0]), max(high, exact[1])))
    middle = pooled_items.mean() if fraction else np.median(pooled_items)
    return Figure(mean, (float(low), float(high)), float(middle), int(has.sum()))


def over_views(values: np.ndarray, stats: ViewStats, keep: np.ndarray | None = None, fraction: bool = False) -> Figure:
    """:func:`per_painting` of a per-view statistic ``values (N,)`` of ``stats``' views (those of ``keep``
    ``(N,)`` bool only, when given): a sequence's value is the mean over its views."""
    values = np.asarray(values, np.float64 if not fraction else bool)
    keep = np.ones(len(values), bool) if keep is None else keep
    ids = np.unique(stats.sequence)
    groups = [values[keep & (stats.sequence == s)] for s in ids]
    paintings = np.array([stats.painting[stats.sequence == s][0] for s in ids])
    return per_painting(groups, paintings, fraction=fraction)


def over_sequences(groups: list[np.ndarray], sequences: list[SequenceStats],
                   reduce: Callable[[np.ndarray], float] = np.mean, fraction: bool = False) -> Figure:
    """:func:`per_painting` of the items of each of ``sequences`` (``groups``, in their order)."""
    return per_painting(groups, np.array([q.painting for q in sequences]), reduce, fraction)


STATISTICS: list[tuple[str, Callable[[ViewStats], Figure], Callable[[ViewStats], Figure] | None]] = [
    ("median luma of painting pixels", lambda s: over_views(s.median_luma, s), None),
    (f"near-white fraction (luma >= {WHITE})", lambda s: over_views(s.near_white, s), None),
    (f"near-black fraction (luma <= {BLACK})", lambda s: over_views(s.near_black, s), None),
    (f"dark area (light < {DARK_LIGHT:g} of the view's median light)", lambda s: over_views(s.dark_area, s), None),
    (f"dark views (median luma < {DARK_MEDIAN})", lambda s: over_views(s.median_luma < DARK_MEDIAN, s, fraction=True),
     None),
    (f"blown-out views (near-white > {BLOWN_VIEW:.0%})",
     lambda s: over_views(s.near_white > BLOWN_VIEW, s, fraction=True), None),
    (f"mostly black views (near-black > {BLACK_VIEW:.0%})",
     lambda s: over_views(s.near_black > BLACK_VIEW, s, fraction=True), None),
    (f"clipped pixels still coloured (a channel >= {CLIPPED}, another < {STILL_COLOURED})",
     lambda s: over_views(s.clipped_coloured, s), None),
    ("detail gain, view 0 (slope of the view's Laplacian on the painting's)",
     lambda s: over_views(s.detail, s, s.view == 0), None),
    ("detail gain, views 1-5", lambda s: over_views(s.detail, s, s.view >= 1), None),
    (f"detail gain, views 1-5, pixels of smallest local scale < {MINIFIED:g}",
     lambda s: over_views(s.detail_minified, s, s.view >= 1), None),
    (f"detail gain, views 1-5, pixels of smallest local scale >= {MINIFIED:g}",
     lambda s: over_views(s.detail_resolved, s, s.view >= 1), None),
    ("cast-shadow fraction (estimated from view / label)", lambda s: over_views(s.shadow_estimated, s), None),
    (f"shadow darkness (estimated: median light ratio where below {DARKENED})",
     lambda s: over_views(s.darkness_estimated, s), None),
    ("occluder coverage of the painting region", lambda s: over_views(s.coverage, s), None),
    ("views with an occluder over the painting", lambda s: over_views(s.occluders_mask > 0, s, fraction=True), None),
    ("occluders per view (mask components)", lambda s: over_views(s.occluders_mask, s), None),
    ("occluders per view (ours: scene, bounding spheres)", lambda s: over_views(s.occluders_scene, s),
     lambda s: over_views(s.occluders_mask, s)),
    ("edge sharpness (largest step / whole step)", lambda s: over_views(s.sharpness, s), None),
    ("occluder saturation (median HSV saturation of occluder pixels)", lambda s: over_views(s.saturation, s), None),
]
"""Rows of views: name, our figure, Blender's figure (None: the same function; else what Blender is
compared with). A sequence's value is the mean over its views (those named), the figure the
per-painting mean of those (:func:`per_painting`)."""

DIAGNOSTICS: list[tuple[str, Callable[[ViewStats], Figure], Callable[[ViewStats], Figure] | None, str]] = [
    ("cast-shadow fraction (ours exact: vs shadows=False)", lambda s: over_views(s.shadow_exact, s),
     lambda s: over_views(s.shadow_estimated, s), "none (Blender's is estimated only)"),
    (f"shadow darkness (ours exact: median light ratio where below {DARKENED})",
     lambda s: over_views(s.darkness_exact, s), lambda s: over_views(s.darkness_estimated, s),
     "none (Blender's is estimated only)"),
    ("cast-shadow fraction (ours estimated on the shadows=False twin: the estimator's false shadows)",
     lambda s: over_views(s.shadow_estimated_twin, s), None, "should be near 0 (the twin has no shadows)"),
]
"""Rows of our own figures that have no Blender counterpart, printed as diagnostics rather than judged
against Blender's interval: name, our figure, the figure of ours it is set against (the ratio of their
means is printed; None: no ratio), and what it is to be read against. The exact shadow rows say how
far the estimate (judged above) is from the truth on our views; the false-shadow row, that the estimate
finds next to nothing where there is nothing to find."""


def matched_errors(q: SequenceStats) -> np.ndarray:
    return q.matcher.errors[q.matcher.success]


SEQUENCE_STATISTICS: list[tuple[str, Callable[[list[SequenceStats]], Figure]]] = [
    ("view 0's effective blur (px, one per sequence)", lambda s: over_sequences([np.array([q.blur]) for q in s], s)),
    ("SIFT keypoints per view on the painting", lambda s: over_sequences([q.matcher.keypoints for q in s], s)),
    ("ratio-test matches per pair of views", lambda s: over_sequences([q.matcher.matches for q in s], s)),
    (f"pairs matched (SIFT + RANSAC corner error < {SUCCESS_PX:g} px)",
     lambda s: over_sequences([q.matcher.success for q in s], s, fraction=True)),
    ("corner error of the matched pairs (px; a sequence's: their median)",
     lambda s: over_sequences([matched_errors(q) for q in s], s, np.median)),
]
"""Rows of whole sequences: name and figure (the same function for ours and Blender's); a sequence's
value is its one figure, the mean over its views or pairs, or the matched pairs' median error."""


def ratio(ours: Figure, reference: Figure) -> tuple[float, str]:
    """Ratio of the per-painting means, and as shown in the table ("n/a" when undefined)."""
    a, b = ours.mean, reference.mean
    value = a / b if b != 0 and np.isfinite(a) and np.isfinite(b) else np.nan
    return value, "n/a" if np.isnan(value) else f"{value:.2f}"


def verdict(ours: Figure, theirs: Figure) -> tuple[str, str, str]:
    """:func:`ratio` of ours to Blender's; whether the two intervals overlap ("overlap", "apart", or
    "n/a" where one is undefined); and the verdict: "yes" when our per-painting mean lies inside
    Blender's interval, else "no". Overlapping intervals are not a pass: with few of our scenes our
    interval is wide enough to overlap almost anything, and a row that passes by overlap alone would
    pass more easily the fewer scenes were rendered."""
    _, shown = ratio(ours, theirs)
    low, high = theirs.interval
    inside = bool(np.isfinite(ours.mean) and np.isfinite(low) and low <= ours.mean <= high)
    (a, b), (c, d) = ours.interval, theirs.interval
    if not all(np.isfinite([a, b, c, d])):
        overlap = "n/a"
    else:
        overlap = "overlap" if a <= d and c <= b else "apart"
    return shown, overlap, "yes" if inside else "no"


def number(value: float, digits: int) -> str:
    return "n/a" if not np.isfinite(value) else f"{value:.{digits}f}"


def digits_of(f: Figure) -> int:
    return 0 if np.isfinite(f.mean) and abs(f.mean) >= 10 else 3


def show(f: Figure, digits: int | None = None) -> str:
    d = digits_of(f) if digits is None else digits
    return f"{number(f.mean, d)} [{number(f.interval[0], d)}, {number(f.interval[1], d)}]"


def table(name: str, ours: ViewStats, our_sequences: list[SequenceStats], theirs: ViewStats,
          their_sequences: list[SequenceStats]) -> str:
    lines = [f"### {name}: {len(ours.median_luma)} views ({len(our_sequences)} sequences, "
             f"{len(np.unique(ours.painting))} paintings) against Blender's {len(theirs.median_luma)} "
             f"({len(their_sequences)} sequences, {len(np.unique(theirs.painting))} paintings)", "",
             f"| statistic | ours: per-painting mean [{CONFIDENCE * 100:g} % interval] | Blender: per-painting mean "
             f"[{CONFIDENCE * 100:g} % interval] | pooled median (fraction): ours / Blender | ratio of means | "
             "intervals | within |", "|---|---|---|---|---|---|---|"]
    figures = [(label, mine(ours), (other or mine)(theirs)) for label, mine, other in STATISTICS]
    figures += [(label, figure(our_sequences), figure(their_sequences)) for label, figure in SEQUENCE_STATISTICS]
    for label, a, b in figures:
        shown, overlap, inside = verdict(a, b)
        d = digits_of(b)
        lines.append(f"| {label} | {show(a, d)} | {show(b, d)} | {number(a.median, d)} / {number(b.median, d)} | "
                     f"{shown} | {overlap} | {inside} |")
    for label, mine, reference, expected in DIAGNOSTICS:
        figure = mine(ours)
        shown = "n/a" if reference is None else f"{ratio(figure, reference(ours))[1]} of ours estimated"
        d = digits_of(figure)
        lines.append(f"| {label} | {show(figure)} | n/a | {number(figure.median, d)} / n/a | {shown} | {expected} "
                     "| diagnostic |")
    return "\n".join(lines)


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``python -m benchmarks.realism``; parsing it runs nothing."""
    parser = argparse.ArgumentParser(prog="python -m benchmarks.realism", description=__doc__.split("\n")[0])
    parser.add_argument("--anchors", required=True, type=Path,
                        help="folder of sequences from the paper's generator (one subfolder per sequence)")
    parser.add_argument("--config", nargs="+", default=["paper_misaligned", "misaligned", "aligned"],
                        help="presets (or YAML paths) to render")
    parser.add_argument("--set", nargs="*", default=[], metavar="KEY=VALUE",
                        help="config overrides applied to every preset (values as YAML)")
    parser.add_argument("--samples", type=int, default=12, help="sequences rendered per preset")
    parser.add_argument("--seed", type=int, default=0)
    return parser


def main(argv: list[str] | None = None) -> None:
    from sidar_torch import load_config

    args = build_parser().parse_args(argv)
    if args.samples < 1:
        raise SystemExit(f"--samples {args.samples}: expected at least 1")
    sequences = anchor_sequences(args.anchors)
    their_views, their_sequences = zip(*[anchor_stats(s, k) for k, s in enumerate(sequences)])
    theirs = ViewStats.concat(list(their_views))
    size = read_rgb(sequences[0] / "source.png").shape[:2]
    overrides = parse_set(args.set)
    print(f"anchors: {len(sequences)} sequences, {len(theirs.median_luma)} views at {size[1]}x{size[0]}; "
          f"ours: {args.samples} samples per preset, seed {args.seed}"
          + (f", overrides {overrides}" if overrides else ""), flush=True)
    for preset in args.config:
        config = load_config(preset, image_size=size, **overrides)
        ours, our_sequences, seconds = our_stats(config, [s / "source.png" for s in sequences], args.samples,
                                                 args.seed)
        print(f"\n{table(preset, ours, our_sequences, theirs, list(their_sequences))}\n\n({seconds:.0f} s for "
              f"{args.samples} samples with their shadows=False twins)", flush=True)


if __name__ == "__main__":
    main()
