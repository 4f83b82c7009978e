"""Cylinder and cone sides are shaded smoothly (no band per facet, no seam), proved by rendering, and
their outlines are the flat-shaded mesh's."""

from dataclasses import replace

import numpy as np
import pytest
import trimesh

from sidar_torch.render import RenderSettings, SceneRenderer, meshes
from sidar_torch.scene import Light, Material, Occluder

from conftest import render_flat_painting

pytestmark = pytest.mark.gl  # renders

SIZE = (192, 256)
LYING = np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])  # the unit primitive's z axis along world -y
MAX_STEP = 10
"""Largest change (8-bit levels) allowed between neighbouring pixels along a row across the side,
where the side is at least 60 pixels wide. With the old flat-shaded 48-sided meshes this scene
steps by 17-19 levels at facet edges (plateaus between); smooth normals give at most 5 on the
cylinder and 8 on the cone (the light's own gradient, steeper where the cone narrows)."""


@pytest.fixture(scope="module")
def renderer():
    renderer = SceneRenderer(RenderSettings(SIZE, shadows=False))
    yield renderer
    renderer.close()


def render(renderer, shape):
    """A close grey cylinder or cone lying across the view (axis vertical in the image, apex down),
    lit from the right by one spot light, no shadows: its side shades from dark to bright across a row."""
    occ = Occluder(shape, np.array([0.0, 0.0, 0.35]), LYING, np.array([0.12, 0.12, 0.3]),
                   Material(np.array([0.8, 0.8, 0.8, 1.0]), 0.0, 0.6))
    light = Light("spot", np.array([[1.2, 0.3, 1.2]]), np.ones(3), 3.0, 1.0, 1.1)
    renderer._meshes = meshes.MeshPool()  # meshes built as the module says now (the test patches it)
    out = render_flat_painting([occ], [light], ambient=0.05, painting=60, size=SIZE, renderer=renderer)
    return out.views[0][..., 0].astype(int), out.masks[0]


def largest_step(image, mask, row):
    """The largest neighbour difference along ``row`` inside the occluder (2 pixels in from its
    outline), and the range of values there."""
    columns = np.flatnonzero(mask[row])
    values = image[row, columns.min() + 2:columns.max() - 1]
    assert len(values) > 55 and np.all(np.diff(columns) == 1)  # one solid run, wide enough to see facets
    return int(np.abs(np.diff(values)).max()), int(values.max() - values.min())


@pytest.mark.parametrize("shape, row", [("cylinder", 40), ("cylinder", 96), ("cone", 20), ("cone", 40)])
def test_the_side_shades_smoothly_and_the_old_flat_mesh_did_not(renderer, shape, row, monkeypatch):
    image, mask = render(renderer, shape)
    step, spread = largest_step(image, mask, row)
    assert spread > 60  # the light sweeps across the side
    assert step <= MAX_STEP, step
    monkeypatch.setitem(meshes.MESHES, shape, replace(meshes.MESHES[shape], side_slope=None))  # flat-shaded, as before
    flat, flat_mask = render(renderer, shape)
    assert largest_step(flat, flat_mask, row)[0] >= MAX_STEP + 5  # the test tells the two apart
    assert np.array_equal(flat_mask, mask)  # same outline


@pytest.mark.parametrize("shape", ["cylinder", "cone"])
def test_the_shaded_surface_is_the_mesh_with_unit_outward_normals_and_flat_caps(shape):
    mesh = meshes.unit_primitive(shape)
    positions, normals = meshes._revolution_normals(mesh, meshes.MESHES[shape].side_slope)
    shaded = trimesh.Trimesh(positions, np.arange(len(positions)).reshape(-1, 3), process=False)
    # The same surface (the cone's facets cut into strips along their own edges), wound outward.
    assert np.isclose(shaded.area, mesh.area, rtol=1e-6) and np.isclose(shaded.volume, mesh.volume, rtol=1e-6)
    plane_distance = np.abs(np.einsum("fa,pfa->pf", mesh.face_normals, positions[:, None] - mesh.triangles[None, :, 0]))
    assert plane_distance.min(axis=1).max() < 1e-6  # every corner lies in the plane of a facet
    assert np.allclose(np.linalg.norm(normals, axis=1), 1, atol=1e-6)
    faces = np.repeat(shaded.face_normals, 3, axis=0)
    assert (np.einsum("ij,ij->i", normals, faces) > 0.95).all()  # within 18 degrees of the facet's
    cap = np.abs(faces[:, 2]) > 0.99
    assert cap.any() and np.allclose(normals[cap], faces[cap], atol=1e-6)
    assert not np.allclose(normals[~cap], faces[~cap], atol=1e-3)  # the side is not flat-shaded
