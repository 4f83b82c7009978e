"""render.light_block: the spot lights' uniform block is laid out as GL lays it out, and filled
as the uniforms were set (the stored digests render every preset through it, bit for bit)."""

import numpy as np
import pytest
from OpenGL import GL

from sidar_torch import SidarDataset
from sidar_torch.render import RenderSettings, shared_renderer
from sidar_torch.render.light_block import BLOCK_NAME, struct_layout
from sidar_torch.choices.render import MAX_SHADOWED_LIGHTS

from conftest import small_config

pytestmark = pytest.mark.gl  # renders


def block_offsets(program_id):
    """``{uniform name: byte offset}`` of every member of the program's light block, as GL reports them."""
    index = GL.glGetUniformBlockIndex(program_id, BLOCK_NAME)
    count = np.zeros(1, np.int32)
    GL.glGetActiveUniformBlockiv(program_id, index, GL.GL_UNIFORM_BLOCK_ACTIVE_UNIFORMS, count)
    indices = np.zeros(int(count[0]), np.int32)
    GL.glGetActiveUniformBlockiv(program_id, index, GL.GL_UNIFORM_BLOCK_ACTIVE_UNIFORM_INDICES, indices)
    offsets = np.zeros(len(indices), np.int32)
    GL.glGetActiveUniformsiv(program_id, len(indices), indices.astype(np.uint32), GL.GL_UNIFORM_OFFSET, offsets)
    names = []
    for i in indices:
        name, length = (GL.GLchar * 128)(), GL.GLsizei(0)
        GL.glGetActiveUniformName(program_id, int(i), 128, length, name)
        names.append(bytes(name)[:length.value].decode())
    return dict(zip(names, offsets.tolist()))


def test_the_block_layout_is_gls_in_every_lit_program():
    """Programs with and without spot-light shadows (the painting's parts without lookups use the
    latter), each member of each light at the offset ``struct_layout`` packs it at."""
    config = small_config("misaligned", n_views=3, n_lights=(2, 3), n_occluders=(2, 3))
    SidarDataset(config=config, seed=0).sample(0)
    renderer = shared_renderer(RenderSettings.from_config(config))
    renderer._platform.make_current()
    seen = set()
    for program in renderer._passes.programs.programs:
        if program.id is None or GL.glGetUniformBlockIndex(program.id, BLOCK_NAME) == GL.GL_INVALID_INDEX:
            continue
        shadows = "SPOT_LIGHT_SHADOWS" in program.defines
        layout, stride = struct_layout(shadows)
        expected = {f"spot_lights[{k}].{member}": k * stride + offset
                    for k in range(MAX_SHADOWED_LIGHTS) for member, (offset, _) in layout.items()}
        assert block_offsets(program.id) == expected, program.defines
        seen.add(shadows)
    assert seen == {False, True}
