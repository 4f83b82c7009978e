"""scene_graph.FlatScene: pyrender's poses and scale, computed once and kept only while they hold."""

import numpy as np
import pyrender
import pytest
import trimesh

from sidar_torch import geometry
from sidar_torch.render.scene_graph import FlatScene, gl_pose


def _pose(rng):
    return gl_pose(*geometry.look_at(rng.normal(size=3) + np.array([0.0, 0.0, 3.0])))


def _scenes(rng):
    """The same two meshes and a light in a FlatScene and a pyrender Scene, and their nodes in each."""
    flat, plain = FlatScene(), pyrender.Scene()
    mesh = pyrender.Mesh.from_trimesh(trimesh.creation.box())
    flat_nodes, plain_nodes = [], []
    for obj in [{"mesh": mesh}, {"mesh": mesh}, {"light": pyrender.SpotLight()}]:
        pose = _pose(rng)
        for scene, nodes in ((flat, flat_nodes), (plain, plain_nodes)):
            nodes.append(pyrender.Node(matrix=pose, **obj))
            scene.add_node(nodes[-1])
    return flat, flat_nodes, plain, plain_nodes


def test_poses_and_scale_are_pyrenders_and_read_only(rng):
    flat, nodes, plain, plain_nodes = _scenes(rng)
    for node, other in zip(nodes, plain_nodes):
        assert flat.get_pose(node).tobytes() == plain.get_pose(other).tobytes()
        assert flat.get_pose(node) is flat.get_pose(node)  # kept
        with pytest.raises(ValueError, match="read-only"):
            flat.get_pose(node)[0, 3] = 1.0
    assert flat.scale == plain.scale


def test_a_moved_node_and_a_new_node_are_seen(rng):
    flat, nodes, _, _ = _scenes(rng)
    before, scale = flat.get_pose(nodes[0]).copy(), flat.scale
    moved = _pose(rng)
    nodes[0].matrix = moved
    assert np.array_equal(flat.get_pose(nodes[0]), moved) and not np.array_equal(moved, before)
    flat.set_pose(nodes[1], before)
    assert np.array_equal(flat.get_pose(nodes[1]), before)
    nodes[2].translation = np.array([0.0, 0.0, 9.0])  # pyrender derives the matrix again
    assert flat.get_pose(nodes[2])[2, 3] == 9.0
    flat.add_node(pyrender.Node(mesh=nodes[0].mesh, translation=np.array([50.0, 0.0, 0.0])))
    assert flat.scale > scale + 40
    flat.remove_node(nodes[0])
    with pytest.raises(ValueError, match="already be in scene"):
        flat.get_pose(nodes[0])


def test_a_parent_node_is_refused():
    flat = FlatScene()
    parent = pyrender.Node()
    flat.add_node(parent)
    with pytest.raises(ValueError, match="parent_node"):
        flat.add_node(pyrender.Node(), parent_node=parent)
