"""The painting's ``supersampled`` texture filter (``programs`` quirk 15), proved by rendering: where a
view does not shrink the painting it is the trilinear filter byte for byte (view 0, the label); where it
does, it is closer to a 4 x 4 supersampled render of the same view than trilinear is, sharper, and
adds no aliasing (closer still after both are blurred, where aliasing would stay as moire)."""

import numpy as np
import pytest
from scipy import ndimage

from sidar_torch import geometry
from sidar_torch.render import RenderSettings, SceneRenderer
from sidar_torch.scene import Camera, SceneSequence, ViewScene

from conftest import LAMBERTIAN, textured_painting

pytestmark = pytest.mark.gl  # renders

SIZE = (96, 128)
SCALE = 4
"""Pixels per side of the supersampled reference's pixel."""


def render(sequence, painting, texture_filter):
    renderer = SceneRenderer(RenderSettings(sequence.image_size, 64, texture_filter=texture_filter, shadows=False))
    try:
        return renderer.render(sequence, painting)
    finally:
        renderer.close()


def linear(srgb):
    c = srgb.astype(np.float64) / 255
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def to_srgb(lin):
    c = np.clip(lin, 0, 1)
    return np.round(255 * np.where(c <= 0.0031308, 12.92 * c, 1.055 * c ** (1 / 2.4) - 0.055)).astype(np.uint8)


def views(size, scale=1):
    """The reference camera, a steep oblique one and a distant oblique one, at ``scale`` times ``size``
    (the same rays through each pixel's ``scale x scale`` sub-pixels)."""
    K, R, t = geometry.reference_camera(size, 1.2)
    cameras = [Camera(K, R, t)]
    for position, zoom in (((0.0, -1.1, 0.55), 1.0), ((0.9, 0.5, 1.6), 0.9)):
        R, t = geometry.look_at(np.array(position))
        cameras.append(Camera(K * np.array([[zoom, 1, 1], [1, zoom, 1], [1, 1, 1]]), R, t))  # focal times zoom
    if scale > 1:  # Kornia pixel centres: small pixel x is big pixel scale x + (scale - 1) / 2
        S = np.array([[scale, 0, (scale - 1) / 2], [0, scale, (scale - 1) / 2], [0, 0, 1.0]])
        cameras = [Camera(S @ c.K, c.R, c.t) for c in cameras]
    shape = (size[0] * scale, size[1] * scale)
    return SceneSequence(shape, tuple(ViewScene(c, (), (), LAMBERTIAN, 1.0) for c in cameras))


def upsampled(painting, scale):
    """The painting as the same bilinear function of its texels, at ``scale`` times its size (linear light)."""
    lin = linear(painting)
    h, w = painting.shape[:2]
    y, x = np.mgrid[0:h * scale, 0:w * scale]
    at = [(y + 0.5) / scale - 0.5, (x + 0.5) / scale - 0.5]
    return to_srgb(np.stack([ndimage.map_coordinates(lin[..., c], at, order=1, mode="nearest") for c in range(3)], -1))


@pytest.fixture(scope="module")
def renders():
    painting = textured_painting(SIZE, seed=4)
    painting = to_srgb(ndimage.gaussian_filter(linear(painting), (0.7, 0.7, 0)))  # detail up to the texel, not noise
    big = render(views(SIZE, SCALE), upsampled(painting, SCALE), "trilinear").views
    reference = linear(big).reshape(len(big), SIZE[0], SCALE, SIZE[1], SCALE, 3).mean(axis=(2, 4))
    return (painting, render(views(SIZE), painting, "trilinear"), render(views(SIZE), painting, "supersampled"),
            reference, render(views(SIZE), painting, "bilinear"))


def test_supersampled_is_trilinear_where_the_view_does_not_shrink_the_painting(renders):
    painting, trilinear, supersampled, _, _ = renders
    assert np.array_equal(supersampled.label, painting) and np.array_equal(trilinear.label, painting)
    assert np.array_equal(supersampled.views[0], trilinear.views[0])  # view 0: one texel per pixel
    assert not np.array_equal(supersampled.views[1:], trilinear.views[1:])


@pytest.mark.parametrize("view", [1, 2])
def test_supersampled_resolves_a_shrunk_painting_as_a_supersampled_render_does(renders, view):
    _, trilinear, supersampled, reference, bilinear = renders
    inside = ndimage.binary_erosion(reference[view].sum(-1) > 0.01, iterations=3)  # the painting, off its edge
    blur = lambda a: ndimage.gaussian_filter(a, (1.0, 1.0, 0))  # noqa: E731
    ref = reference[view]
    ours = {name: linear(r.views[view]) for name, r in (("tri", trilinear), ("sup", supersampled), ("bi", bilinear))}
    error = {name: float(np.mean((a - ref)[inside] ** 2)) for name, a in ours.items()}
    low = {name: float(np.mean((blur(a) - blur(ref))[inside] ** 2)) for name, a in ours.items()}  # moire stays
    detail = {name: float(np.mean((a - blur(a))[inside] ** 2)) for name, a in {**ours, "ref": ref}.items()}
    assert inside.sum() > 2000
    assert error["sup"] < 0.6 * error["tri"]  # closer to the supersampled render than trilinear ...
    assert low["sup"] < low["tri"]  # ... also after a blur of both
    # Sharper than trilinear: between 1 and 2 texels per pixel the lookups spread over part of the pixel
    # only (as sharp as the paper's renders), so somewhat sharper than the box-filtered reference; bilinear
    # (one lookup of the full-size texture) is sharper still, by aliasing.
    assert detail["tri"] < detail["ref"] < detail["sup"] < 1.5 * detail["ref"] < detail["bi"]
