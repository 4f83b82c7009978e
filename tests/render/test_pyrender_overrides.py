"""``render.pyrender_overrides`` overrides private methods of pyrender: each must still exist in the installed
pyrender with the parameters ours are called with, or a pyrender release would silently bypass
an override (``pyproject.toml`` bounds ``pyrender2`` below its next minor release for the same reason)."""

import inspect

import numpy as np
import pyrender
import pytest
import trimesh
from pyrender.shader_program import ShaderProgram, ShaderProgramCache

from sidar_torch.render import RenderSettings, shared_renderer
from sidar_torch.render.pyrender_overrides import GLRenderer, ProgramCache, RankedNode, _PatchedProgram, add_node
from sidar_torch.render.scene_graph import FlatScene

from conftest import SMALL

OVERRIDES = {
    (GLRenderer, pyrender.Renderer): (
        "__del__", "_bind_and_draw_primitive", "_bind_lighting", "_compute_max_n_lights",
        "_configure_forward_pass_viewport", "_configure_shadow_mapping_viewport", "_get_camera_matrices",
        "_get_light_cam_matrices", "_get_primitive_program", "_reset_active_textures", "_sorted_mesh_nodes",
        "_update_context"),
    (ProgramCache, ShaderProgramCache): ("get_program",),
    (_PatchedProgram, ShaderProgram): ("_add_to_context", "_load", "set_uniform"),
    (RankedNode, pyrender.Node): ("__hash__", "matrix", "rotation", "scale", "translation"),
    (FlatScene, pyrender.Scene): ("add_node", "get_pose", "remove_node", "scale"),
}
"""Per (our class, pyrender's), every attribute of ours that replaces one of pyrender's."""


def parameters(function):
    return list(inspect.signature(function).parameters)[1:] if callable(function) else None


@pytest.mark.parametrize("ours, theirs", list(OVERRIDES), ids=lambda c: c.__name__)
def test_every_override_replaces_a_pyrender_method_with_the_same_parameters(ours, theirs):
    names = OVERRIDES[ours, theirs]
    missing = [name for name in names if not hasattr(theirs, name)]
    assert not missing, f"pyrender's {theirs.__name__} no longer has {missing}: the overrides would be bypassed"
    for name in names:
        mine, base = inspect.getattr_static(ours, name), inspect.getattr_static(theirs, name)
        if callable(mine) and callable(base):
            assert parameters(mine)[:len(parameters(base))] == parameters(base), (name, parameters(base))
    replaced = {name for name in vars(ours) if hasattr(theirs, name)
                and (not name.startswith("__") or name in ("__del__", "__hash__", "__len__"))}
    assert replaced == set(names), f"list every override here: {sorted(replaced ^ set(names))}"


@pytest.mark.gl
def test_opaque_meshes_are_drawn_nearest_first_and_blended_ones_in_pyrenders_order():
    """Opaque: nearest first (the depth test then rejects hidden fragments before shading; no
    blending, so the pixels are those of any order). Blended: farthest first, pyrender's order,
    which their blending depends on."""
    scene = FlatScene()
    add_node(scene, np.eye(4), camera=pyrender.PerspectiveCamera(yfov=1.0))
    nodes = {}
    for kind, alpha_mode in (("opaque", "OPAQUE"), ("blended", "BLEND")):
        for distance in (2.0, 1.0, 3.0):
            material = pyrender.MetallicRoughnessMaterial(alphaMode=alpha_mode, baseColorFactor=(1, 1, 1, 0.5))
            mesh = pyrender.Mesh.from_trimesh(trimesh.creation.box(), material=material)
            pose = np.eye(4)
            pose[2, 3] = -distance
            nodes[kind, distance] = add_node(scene, pose, mesh=mesh)
    order = shared_renderer(RenderSettings(SMALL))._gl._sorted_mesh_nodes(scene)
    assert order == [nodes["opaque", d] for d in (1.0, 2.0, 3.0)] + [nodes["blended", d] for d in (3.0, 2.0, 1.0)]
    theirs = pyrender.Renderer._sorted_mesh_nodes(None, scene)
    assert order[3:] == theirs[3:]
