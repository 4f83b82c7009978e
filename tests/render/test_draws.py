"""The draw list (``render.draws``, ``render.scene_graph``): draw order, and the camera and scene values
that pyrender computed when it drew (its formulas are the reference the stored digests were recorded with)."""

import re
from pathlib import Path

import numpy as np
import pyrender
import pytest
import trimesh

from sidar_torch import geometry
from sidar_torch.render.draws import Surface, ViewDraws, world_pose
from sidar_torch.render.gpu import GpuMesh
from sidar_torch.render.passes import LitPass, ShadowFractionPass
from sidar_torch.render.scene_graph import camera_draws, clip_range, gl_material, gl_pose
from sidar_torch.scene import Camera, Material

from conftest import SMALL

PACKAGE = Path(__file__).resolve().parents[2] / "sidar_torch"


def test_opaque_surfaces_are_drawn_nearest_first_and_transparent_ones_farthest_first():
    """Opaque: nearest first (the depth test then rejects hidden fragments before shading; no
    blending, so the pixels are those of any order). Transparent: farthest first, which blending needs."""
    camera = np.eye(4)
    camera[2, 3] = 10.0
    glass = Material(np.array([1.0, 1.0, 1.0, 0.5]), 0.0, 1.0)
    assert glass.transparent
    surfaces = {}
    for kind, material in (("opaque", Material(np.ones(4), 0.0, 1.0)), ("blended", glass)):
        for distance in (2.0, 1.0, 3.0):
            pose = np.eye(4)
            pose[2, 3] = 10.0 - distance
            surfaces[kind, distance] = Surface(GpuMesh.from_trimesh(trimesh.creation.box(), smooth=False),
                                               world_pose(pose), gl_material(material))
    view = ViewDraws(camera, np.eye(4), np.zeros(3, np.float32), surfaces["opaque", 2.0],
                     [s for key, s in surfaces.items() if key != ("opaque", 2.0)])
    order = view.ordered(view.surfaces)
    assert order == [surfaces["opaque", d] for d in (1.0, 2.0, 3.0)] + [surfaces["blended", d] for d in (3.0, 2.0, 1.0)]


def test_the_camera_is_pyrenders_intrinsics_camera_at_the_pixel_centre_shift():
    rng = np.random.default_rng(0)
    K = geometry.reference_camera(SMALL, 1.0)[0]
    for _ in range(5):
        position = np.array([*rng.uniform(-0.5, 0.5, 2), rng.uniform(0.3, 2.0)])
        camera = Camera(K, *geometry.look_at(position))
        pose, projection = camera_draws(camera, SMALL)
        znear, zfar = clip_range(camera, SMALL)
        theirs = pyrender.IntrinsicsCamera(fx=K[0, 0], fy=K[1, 1], cx=K[0, 2] + 0.5, cy=K[1, 2] + 0.5, znear=znear, zfar=zfar)
        assert np.array_equal(projection, theirs.get_projection_matrix(SMALL[1], SMALL[0]))
        assert np.array_equal(pose, gl_pose(camera.R, camera.t))


def test_the_view_scale_is_pyrenders_scene_scale():
    rng = np.random.default_rng(1)
    meshes = [trimesh.creation.icosphere(2), trimesh.creation.box(), trimesh.creation.cylinder(0.5, 1.0)]
    scene = pyrender.Scene()
    surfaces = []
    for mesh in meshes:
        pose = trimesh.transformations.random_rotation_matrix(rng.random(3))
        pose[:3, 3] = rng.normal(size=3)
        scene.add(pyrender.Mesh.from_trimesh(mesh), pose=pose)
        surfaces.append(Surface(GpuMesh.from_trimesh(mesh, smooth=True), world_pose(pose),
                                gl_material(Material(np.ones(4), 0.0, 1.0))))
    view = ViewDraws(np.eye(4), np.eye(4), np.zeros(3, np.float32), surfaces[0], surfaces[1:])
    assert view.scale == scene.scale


def test_each_pass_checks_its_own_combination():
    solid, glass, light = object(), object(), object()  # surfaces and an emitter: only their identity is read
    colour = LitPass((solid, glass), (glass,), (light,), [], stale=(light,), shadow_free=True, stencil=True)
    assert colour.tinted() == [glass]
    with pytest.raises(ValueError, match="transmitting: expected some of casters"):
        LitPass((solid,), (glass,), (light,))
    with pytest.raises(ValueError, match="stale: expected some of shadowed"):
        LitPass(shadowed=(light,), stale=(object(),))
    with pytest.raises(ValueError, match="shadow_free: needs a shadowed emitter"):
        LitPass((solid,), shadow_free=True)
    with pytest.raises(ValueError, match="stencil: needs painting_parts"):
        LitPass(stencil=True)
    assert ShadowFractionPass((solid,), (), (light,), []).step == "shadow_mask"
    with pytest.raises(ValueError, match="shadowed: expected at least one emitter"):
        ShadowFractionPass((solid,))
    with pytest.raises(ValueError, match="transmitting: expected some of casters"):
        ShadowFractionPass((solid,), (glass,), (light,))


def test_the_package_uses_no_private_pyrender_name_and_subclasses_nothing_of_it():
    """pyrender opens the GL context and nothing else: a pyrender release cannot change a pixel quietly."""
    found = []
    for path in PACKAGE.rglob("*.py"):
        for number, line in enumerate(path.read_text().splitlines(), 1):
            if re.search(r"pyrender\.[A-Za-z.]*\._|class .*\(pyrender\.", line):
                found.append(f"{path.relative_to(PACKAGE)}:{number}: {line.strip()}")
    assert not found, found
