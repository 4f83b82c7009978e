"""View effects beyond the paper: coloured background, pixel filter, exposure and gamma jitter, sensor
noise, JPEG.

Each is a per-pixel 2-D change of a rendered view, switched on in :class:`~sidar_torch.config.SidarConfig`
(all off by default). None moves a pixel, so every homography stays exact; the label and the
masks are never touched. They follow a camera's pipeline, in this order, per view:

1. **background**: pixels where the renderer drew nothing (``RenderedSequence.background``) take
   the view's colour (8-bit sRGB);
2. the 8-bit sRGB values are decoded to linear light (exact sRGB curve, float32);
   **pixel filter**: a separable Gaussian of ``pixel_filter_sigma`` pixels (borders reflected), as a
   camera's optics and a path tracer's pixel filter blur the light itself;
3. **exposure**: ``x * 2 ** stops``;
4. **sensor noise**: ``+ sqrt(read ** 2 + shot * x) * n``, ``n`` standard normal per pixel and
   channel: the Gaussian approximation of Poisson shot noise (``x / shot`` photons) plus
   Gaussian read noise (Foi et al.'s Poissonian-Gaussian model). Linear light is where a
   sensor's noise lives: shot noise grows with the light collected, not with the encoded value;
5. clipping to [0, 1] (the sensor saturates), then **gamma**: ``x ** gamma``;
6. exact sRGB encoding, rounded to 8 bits;
7. **JPEG** at the view's quality (Pillow, in memory, 4:2:0 chroma subsampling), decoded back.

Steps 2-6 run only when the pixel filter, exposure jitter or sensor noise is on, else the 8-bit values pass
through untouched (without noise they are a function of the 8-bit value: a 256-entry table per
view). Exposure acts on the already rendered 8-bit view: pixels the renderer blew out (255)
stay flat when darkened.

Background limit: a transparent occluder in front of the background was blended over black by
the renderer and stays so (darker than it would look over the colour); nearly clear glass there
(opacity under about 0.06) counts as background and takes the colour. Both are masked pixels.

Randomness: :func:`draw_effects` draws, from the sample's generator after the scene sampler has
drawn everything, and only for the effects that are on, in this order: background colours,
exposure stops and gammas, read and shot noise levels, JPEG qualities (one per view each, or
one colour per sample), then the noise field. So switching effects on leaves the scene, the
masks, the label and the homographies unchanged.
"""

from __future__ import annotations

import io
from dataclasses import dataclass

import numpy as np
import torch
from PIL import Image

from ..config import SidarConfig

__all__ = ["ViewEffects", "apply_effects", "blur_painting", "draw_effects", "enabled_effects", "gaussian_filter",
           "jpeg_roundtrip", "linear_to_srgb", "srgb_to_linear"]

def srgb_to_linear(srgb: torch.Tensor) -> torch.Tensor:
    """Decode sRGB values in [0, 1] to linear light (the exact piecewise sRGB curve), any shape."""
    return torch.where(srgb <= 0.04045, srgb / 12.92, ((srgb + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(linear: torch.Tensor, out: torch.Tensor | None = None) -> torch.Tensor:
    """Encode linear light (>= 0; 1 is white) to sRGB values (the exact curve), any shape.

    ``out``: a tensor of ``linear``'s shape and dtype to write the result to (``linear`` itself
    encodes in place, sparing the memory of a copy); by default a new tensor.
    """
    low = linear <= 0.0031308
    low_values = linear * 12.92
    out = torch.clamp(linear, min=0, out=out).pow_(1 / 2.4).mul_(1.055).sub_(0.055)
    return torch.where(low, low_values, out, out=out)


_DECODED = srgb_to_linear(torch.arange(256, dtype=torch.float64) / 255).float().numpy()
"""Linear light of each 8-bit sRGB value, ``(256,)`` float32."""


@dataclass(frozen=True)
class ViewEffects:
    """The drawn effects of one sample's ``V`` views of ``H x W`` pixels; ``None``: effect off.

    Attributes:
        background: ``(V, 3)`` uint8 sRGB colour of each view's background.
        gain: ``(V,)`` float64 factor on linear intensity (``2 ** stops``).
        gamma: ``(V,)`` float64 exponent on linear intensity (with ``gain``).
        read_noise: ``(V,)`` float64 read-noise standard deviation, linear.
        shot_noise: ``(V,)`` float64 shot-noise scale (variance per unit of linear intensity).
        noise: ``(V, H, W, 3)`` float32 standard normal field (with the noise levels).
        jpeg_quality: ``(V,)`` int64 JPEG quality.
        blur_sigma: the pixel filter's standard deviation, pixels (``pixel_filter_sigma``; drawn
            from nothing).
    """

    background: np.ndarray | None = None
    gain: np.ndarray | None = None
    gamma: np.ndarray | None = None
    read_noise: np.ndarray | None = None
    shot_noise: np.ndarray | None = None
    noise: np.ndarray | None = None
    jpeg_quality: np.ndarray | None = None
    blur_sigma: float | None = None


def enabled_effects(config: SidarConfig) -> list[str]:
    """Names of the config switches of the view effects that are on."""
    switches = {"background": config.background != "black", "pixel_filter_sigma": config.pixel_filter_sigma > 0,
                "exposure_jitter": config.exposure_jitter,
                "sensor_noise": config.sensor_noise, "jpeg": config.jpeg}
    return [name for name, on in switches.items() if on]


def draw_effects(config: SidarConfig, n_views: int, image_size: tuple[int, int],
                 rng: np.random.Generator | None) -> ViewEffects | None:
    """Draw the view effects ``config`` switches on (order in the module docstring).

    Args:
        n_views, image_size: ``V`` and ``(H, W)`` of the sample.
        rng: the sample's generator, after the scene sampler drew from it; may be ``None`` when
            every effect is off.

    Returns:
        the effects, or ``None`` when every effect is off (nothing is drawn then).

    Raises:
        ValueError: an effect is on and ``rng`` is ``None``.
    """
    enabled = enabled_effects(config)
    if not enabled:
        return None
    blur = config.pixel_filter_sigma if config.pixel_filter_sigma > 0 else None
    if enabled == ["pixel_filter_sigma"]:  # the one effect that draws nothing
        return ViewEffects(blur_sigma=blur)
    if rng is None:
        raise ValueError(f"rng: config switches on view effects {enabled}, which draw from the sample's "
                         f"numpy Generator; pass the generator that drew the scene (got None)")
    background = gain = gamma = read = shot = noise = quality = None
    if config.background != "black":
        colours = rng.uniform(*config.background_level, size=(n_views if config.background == "view" else 1, 3))
        background = np.broadcast_to(np.round(colours * 255).astype(np.uint8), (n_views, 3)).copy()
    if config.exposure_jitter:
        gain = 2.0 ** rng.uniform(*config.exposure_stops, size=n_views)
        gamma = rng.uniform(*config.gamma, size=n_views)
    if config.sensor_noise:
        read = rng.uniform(*config.read_noise, size=n_views)
        shot = rng.uniform(*config.shot_noise, size=n_views)
    if config.jpeg:
        quality = rng.integers(config.jpeg_quality[0], config.jpeg_quality[1] + 1, size=n_views)
    if config.sensor_noise:
        noise = rng.standard_normal((n_views, *image_size, 3), dtype=np.float32)
    return ViewEffects(background, gain, gamma, read, shot, noise, quality, blur)


def jpeg_roundtrip(view: np.ndarray, quality: int) -> np.ndarray:
    """``view`` ``(H, W, 3)`` uint8 compressed as JPEG at ``quality`` (1-100, 4:2:0 chroma) and
    decoded, in memory, ``(H, W, 3)`` uint8."""
    buffer = io.BytesIO()
    Image.fromarray(view).save(buffer, format="JPEG", quality=int(quality), subsampling="4:2:0")
    return np.asarray(Image.open(buffer).convert("RGB"))


def apply_effects(views: np.ndarray, background: np.ndarray, effects: ViewEffects | None) -> np.ndarray:
    """The views with ``effects`` applied (the pipeline of the module docstring).

    Args:
        views: ``(V, H, W, 3)`` uint8 sRGB rendered views (not modified).
        background: ``(V, H, W)`` bool, True where the renderer drew nothing
            (``RenderedSequence.background``).
        effects: from :func:`draw_effects`; ``None`` returns ``views`` itself.

    Returns:
        ``(V, H, W, 3)`` uint8 sRGB.
    """
    if effects is None:
        return views
    out = views.copy()
    if effects.background is not None:
        for view, where, colour in zip(out, background, effects.background):
            view[where] = colour
    if effects.noise is not None or effects.blur_sigma is not None:
        out = _sensor(out, effects)
    elif effects.gain is not None:
        # Without noise a view's change depends on the 8-bit value alone: tabulate it per view.
        tables = _sensor(np.broadcast_to(np.arange(256, dtype=np.uint8), (len(out), 1, 1, 256)), effects)
        out = np.stack([table[0, 0][view] for table, view in zip(tables, out)])
    if effects.jpeg_quality is not None:
        out = np.stack([jpeg_roundtrip(view, q) for view, q in zip(out, effects.jpeg_quality)])
    return out


def gaussian_filter(images: torch.Tensor, sigma: float) -> torch.Tensor:
    """``images`` ``(V, H, W, C)`` float32 filtered by a normalised separable Gaussian of standard
    deviation ``sigma`` pixels (taps to 3 sigma), borders reflected; a new tensor of the same shape.
    One depthwise convolution per axis (13x cheaper on one core than a convolution of one channel
    per image)."""
    radius = max(1, int(np.ceil(3 * sigma)))
    taps = torch.exp(-0.5 * (torch.arange(-radius, radius + 1, dtype=torch.float64) / sigma) ** 2)
    kernel = (taps / taps.sum()).float()
    channels = images.shape[3]
    x = images.permute(0, 3, 1, 2)  # (V, C, H, W)
    for pad, shape in (((radius, radius, 0, 0), (1, -1)), ((0, 0, radius, radius), (-1, 1))):
        side = x.shape[3] if pad[0] else x.shape[2]
        x = torch.nn.functional.pad(x, pad, mode="reflect" if side > radius else "replicate")
        x = torch.nn.functional.conv2d(x, kernel.view(1, 1, *shape).repeat(channels, 1, 1, 1), groups=channels)
    return x.permute(0, 2, 3, 1).contiguous()


def blur_painting(painting: np.ndarray, sigma: float) -> np.ndarray:
    """``painting`` ``(H, W, 3)`` uint8 sRGB filtered in linear light by a Gaussian of ``sigma`` texels
    (:func:`gaussian_filter`, borders reflected), re-encoded to ``(H, W, 3)`` uint8 sRGB: the texture the
    views see with ``texture_blur_sigma`` (Cycles' filtering of an image texture). ``sigma`` must be > 0."""
    x = gaussian_filter(torch.from_numpy(_DECODED[painting][None]), sigma)
    return linear_to_srgb(x, out=x).mul_(255).round_().to(torch.uint8).numpy()[0]


def _sensor(values: np.ndarray, effects: ViewEffects) -> np.ndarray:
    """Steps 2-6 of the module docstring on ``(V, ...)`` uint8 sRGB values (4 dimensions; the noise
    field, if any, of their shape), per view; uint8 of the same shape. Works in place on one
    float32 copy: fresh arrays of a sample's size cost more than the arithmetic."""
    per_view = (-1, 1, 1, 1)
    x = torch.from_numpy(_DECODED[values])
    if effects.blur_sigma is not None:
        x = gaussian_filter(x, effects.blur_sigma)
    if effects.gain is not None:
        x *= torch.from_numpy(effects.gain).float().view(per_view)
    if effects.noise is not None:
        read, shot = (torch.from_numpy(a).float().view(per_view) for a in (effects.read_noise, effects.shot_noise))
        x += x.clamp(min=0).mul_(shot).add_(read**2).sqrt_().mul_(torch.from_numpy(effects.noise))
    x.clamp_(0, 1)
    if effects.gamma is not None:
        x.pow_(torch.from_numpy(effects.gamma).float().view(per_view))
    return linear_to_srgb(x, out=x).mul_(255).round_().to(torch.uint8).numpy()
