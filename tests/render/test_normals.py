"""The normals output (issue 47), proved by rendering: on the painting each camera's view of the plane's
normal, on a sphere the direction from its centre to the surface point the camera's ray hits."""

import numpy as np
import pytest
import torch

from sidar_torch import SidarDataset, geometry
from sidar_torch.render import RenderSettings, shared_renderer
from sidar_torch.scene import Camera, Light, Material, Occluder, SceneSequence, ViewScene

from conftest import SMALL, WHITE, small_config, textured_painting

pytestmark = pytest.mark.gl

SIZE = (120, 160)
SPHERE = Occluder("sphere", np.array([0.05, -0.04, 0.25]), np.eye(3), np.full(3, 0.12),
                  Material(np.array([0.8, 0.3, 0.2, 1.0]), 0.0, 0.6))
CAMERAS = [Camera(*geometry.reference_camera(SIZE, 0.9)),
           Camera(geometry.intrinsics_from_fov(70, SIZE), *geometry.look_at(np.array([0.35, -0.25, 0.8]))),
           Camera(geometry.intrinsics_from_fov(80, SIZE), *geometry.look_at(np.array([-0.3, 0.3, 0.75])))]


def camera_rays(K, size):
    """``(3, H W)`` camera-frame directions (z = 1) through every pixel centre, row by row (Kornia pixels)."""
    v, u = np.meshgrid(np.arange(size[0], dtype=float), np.arange(size[1], dtype=float), indexing="ij")
    return np.linalg.solve(K, np.stack([u.ravel(), v.ravel(), np.ones(u.size)]))


@pytest.fixture(scope="module")
def sphere_scene():
    light = Light("spot", np.array([[0.2, 0.1, 2.0]]), np.ones(3), 6.0, 0.9, 1.0)
    sequence = SceneSequence(SIZE, tuple(ViewScene(camera, (light,), (SPHERE,), WHITE, 0.3) for camera in CAMERAS))
    rendered = shared_renderer(RenderSettings(SIZE, outputs=frozenset({"normals"}))).render(
        sequence, textured_painting(SIZE))
    return sequence, rendered


def test_painting_normals_are_the_planes_normal_in_each_cameras_frame():
    dataset = SidarDataset(config=small_config("misaligned", normals_output=True), seed=3)
    for index in range(2):
        sample = dataset.sample(index)
        normals, R, t = sample["normals"], sample["R"].double(), sample["t"].double()
        assert normals.shape == (3, 3, *SMALL) and normals.dtype == torch.float32
        painting = sample["masks"][:, 0] == 0
        for i in range(len(normals)):
            expected = R[i] @ torch.tensor([0.0, 0.0, 1.0], dtype=torch.float64)  # the painting faces +z
            assert expected @ t[i] < 0  # towards the camera: n . (R X + t) < 0 on the plane
            seen = normals[i].double().permute(1, 2, 0)[painting[i]]
            assert len(seen) > 500
            assert (seen - expected).abs().max() < 1e-3, (index, i)


def test_sphere_normals_point_from_its_centre_to_the_surface_the_ray_hits(sphere_scene):
    sequence, rendered = sphere_scene
    K, R, t = sequence.cameras()
    radius = SPHERE.scale[0]
    checked = 0
    for i in range(len(CAMERAS)):
        d = camera_rays(K[i], SIZE)  # camera frame
        centre = R[i] @ SPHERE.position + t[i]
        b, c = (d * centre[:, None]).sum(0), centre @ centre - radius ** 2
        disc = b * b - (d * d).sum(0) * c
        s = (b - np.sqrt(np.maximum(disc, 0))) / (d * d).sum(0)
        expected = d * s - centre[:, None]
        expected /= np.linalg.norm(expected, axis=0)
        cosine = -(expected * d).sum(0) / np.linalg.norm(d, axis=0)  # the ray against the normal: 0 grazing
        hit = (disc > 0) & (cosine > 0.3) & ~rendered.background[i].ravel()
        got = rendered.outputs["normals"][i].reshape(-1, 3).T.astype(np.float64)
        assert hit.sum() > 200, i
        assert np.linalg.norm(got[:, hit] - expected[:, hit], axis=0).max() < 0.02, i
        checked += hit.sum()
    assert checked > 1000


def test_normals_are_unit_where_a_surface_is_drawn_and_zero_elsewhere_and_change_no_other_pixel(sphere_scene):
    sequence, rendered = sphere_scene
    normals = rendered.outputs["normals"]
    assert normals.shape == (len(CAMERAS), *SIZE, 3) and normals.dtype == np.float32
    drawn = ~rendered.background
    assert np.abs(np.linalg.norm(normals[drawn], axis=-1) - 1).max() < 1e-5
    assert not normals[~drawn].any() and (~drawn).any()
    without = shared_renderer(RenderSettings(SIZE)).render(sequence, textured_painting(SIZE))
    assert np.array_equal(without.views, rendered.views) and np.array_equal(without.masks, rendered.masks)
    assert np.array_equal(without.label, rendered.label) and set(rendered.outputs) == {"normals"}
