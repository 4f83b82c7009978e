"""The spot lights' uniforms as one std140 uniform block (``programs`` quirk 14).

pyrender declares ``uniform SpotLight spot_lights[MAX_SPOT_LIGHTS]`` and sets every member of
every light as a uniform of its own, in every program that shades: about 90 GL calls per program,
three programs per lit pass, 0.5 ms of a 192 x 256 view. Our shader (``shaders/surface.frag``) declares the array
as a uniform block instead (``layout(std140) uniform SpotLights``), so a pass packs its lights
once into a buffer (:class:`LightBlocks`) that every program of the pass reads.

std140 (GLSL 4.60, 7.6.2.2) places a scalar on 4 bytes, a ``vec3`` and a ``vec4`` on 16, a
``mat4`` as four column ``vec4`` (column major), and pads a structure to a multiple of 16 bytes,
the stride of an array of them; :func:`struct_layout` applies these rules to our
``SpotLight``. Programs with spot-light shadows have two more members (``shadow_layer``,
``light_matrix``), so two layouts exist, each with its own buffer and binding point
(:data:`BINDINGS`). A program checks its block's size against the layout when it is linked.

The values reach GL as the uniform calls sent them: float members as float32, ``int`` members as
int32, the light matrix as the float32 matrix GL transposed from row major.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from OpenGL import GL

from ..choices.render import MAX_SHADOWED_LIGHTS

__all__ = ["BINDINGS", "BLOCK_NAME", "LightBlocks", "bind_program_block", "block_size", "struct_layout"]

BLOCK_NAME = "SpotLights"
"""The uniform block's name in ``shaders/surface.frag``."""

BINDINGS = {False: 1, True: 2}
"""Uniform buffer binding point of each layout, by whether it has the shadow members."""

_MEMBERS = (("color", "vec3"), ("intensity", "float"), ("range", "float"), ("position", "vec3"),
            ("direction", "vec3"), ("light_angle_scale", "float"), ("light_angle_offset", "float"),
            ("smooth_falloff", "float"), ("soft_depth", "vec4"), ("soft_reach", "float"),
            ("group_position", "vec3"), ("group_direction", "vec3"), ("group_size", "int"))
"""``shaders/surface.frag``'s ``SpotLight`` members in declaration order."""

_SHADOW_MEMBERS = (("shadow_layer", "int"), ("light_matrix", "mat4"))
"""The members only programs with spot-light shadows declare, after the others."""

_STD140 = {"float": (4, 4), "int": (4, 4), "vec3": (16, 12), "vec4": (16, 16), "mat4": (16, 64)}
"""std140 base alignment and size (bytes) of each member type."""


def struct_layout(shadows: bool) -> tuple[dict[str, tuple[int, str]], int]:
    """The std140 layout of one ``SpotLight``: ``({member: (byte offset, type)}, stride in bytes)``.

    Args:
        shadows: the layout of programs with spot-light shadows (two more members).
    """
    offsets: dict[str, tuple[int, str]] = {}
    offset = 0
    for name, kind in _MEMBERS + (_SHADOW_MEMBERS if shadows else ()):
        align, size = _STD140[kind]
        offset = -(-offset // align) * align
        offsets[name] = (offset, kind)
        offset += size
    return offsets, -(-offset // 16) * 16


def block_size(shadows: bool) -> int:
    """Bytes of the whole block: :data:`~sidar_torch.choices.render.MAX_SHADOWED_LIGHTS` lights."""
    return struct_layout(shadows)[1] * MAX_SHADOWED_LIGHTS


def bind_program_block(program_id: int, shadows: bool) -> None:
    """Point a linked program's ``SpotLights`` block (if it has one) at its layout's binding point.

    Raises:
        RuntimeError: the block's size is not the layout's (the shader's struct and
            :func:`struct_layout` disagree).
    """
    index = GL.glGetUniformBlockIndex(program_id, BLOCK_NAME)
    if index == GL.GL_INVALID_INDEX:
        return
    size = np.zeros(1, np.int32)
    GL.glGetActiveUniformBlockiv(program_id, index, GL.GL_UNIFORM_BLOCK_DATA_SIZE, size)
    size = int(size[0])
    if size != block_size(shadows):
        raise RuntimeError(f"uniform block {BLOCK_NAME}: {size} bytes in the shader, {block_size(shadows)} in "
                           f"light_block.struct_layout(shadows={shadows})")
    GL.glUniformBlockBinding(program_id, index, BINDINGS[shadows])


class LightBlocks:
    """The two uniform buffers of one GL context (one per layout), bound to :data:`BINDINGS`."""

    def __init__(self) -> None:
        self._buffers = {}
        for shadows, binding in BINDINGS.items():
            buffer = int(GL.glGenBuffers(1))
            GL.glBindBuffer(GL.GL_UNIFORM_BUFFER, buffer)
            GL.glBufferData(GL.GL_UNIFORM_BUFFER, block_size(shadows), None, GL.GL_DYNAMIC_DRAW)
            GL.glBindBufferBase(GL.GL_UNIFORM_BUFFER, binding, buffer)
            self._buffers[shadows] = buffer
        GL.glBindBuffer(GL.GL_UNIFORM_BUFFER, 0)

    def upload(self, lights: dict[str, list[Any]], count: int, shadows: bool) -> None:
        """Write ``count`` lights into the buffer of the ``shadows`` layout, light ``k`` at ``k``
        strides; members not given are 0, members of the other layout are ignored.

        Args:
            lights: ``{member: [value of light 0, ..., of light count - 1]}``, values Python or NumPy
                numbers, ``(3,)`` or ``(4,)`` arrays, ``(4, 4)`` row-major matrices for ``light_matrix``.
            count: the number of lights, at most ``MAX_SHADOWED_LIGHTS``.
        """
        offsets, stride = struct_layout(shadows)
        floats = np.zeros((count, stride // 4), np.float32)
        ints = floats.view(np.int32)
        for name, values in lights.items():
            if name not in offsets:
                continue
            offset, kind = offsets[name]
            at = offset // 4
            if kind == "int":
                ints[:, at] = values
            elif kind == "mat4":
                floats[:, at:at + 16] = np.asarray(values).transpose(0, 2, 1).reshape(count, 16)  # column major
            else:
                columns = np.asarray(values).reshape(count, -1)
                floats[:, at:at + columns.shape[1]] = columns
        GL.glBindBuffer(GL.GL_UNIFORM_BUFFER, self._buffers[shadows])
        GL.glBufferSubData(GL.GL_UNIFORM_BUFFER, 0, floats.nbytes, floats)
        GL.glBindBuffer(GL.GL_UNIFORM_BUFFER, 0)
