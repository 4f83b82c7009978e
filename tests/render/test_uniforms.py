"""render.uniforms: vector and matrix uniforms set through ctypes reach GL as PyOpenGL sends them."""

import numpy as np
import pytest
from OpenGL import GL
from OpenGL.GL import shaders

from sidar_torch.render import RenderSettings, SceneRenderer
from sidar_torch.render.uniforms import set_uniform_array

VERTEX = """#version 330 core
uniform vec3 v3; uniform vec2 v2; uniform ivec4 i4; uniform uvec2 u2; uniform float f1;
uniform mat4 m4; uniform mat3 m3;
out vec4 keep;
void main() {
    keep = vec4(v3, v2.x + v2.y) + vec4(i4) + vec4(u2, f1, 0.0) + m4[1] + vec4(m3[2], 0.0);
    gl_Position = vec4(0.0);
}
"""
FRAGMENT = """#version 330 core
in vec4 keep; out vec4 color;
void main() { color = keep; }
"""

VALUES = {"v3": (np.array([0.1, -2.5, 1e-7]), "f", GL.glGetUniformfv, np.float32),
          "v2": (np.array([3, 4], dtype=np.int64), "f", GL.glGetUniformfv, np.float32),
          "i4": (np.array([-1, 2, -3, 2**31 - 1], dtype=np.int64), "i", GL.glGetUniformiv, np.int32),
          "u2": (np.array([7, 2**32 - 1], dtype=np.uint64), "u", GL.glGetUniformuiv, np.uint32),
          "f1": (np.array([0.3]), "f", GL.glGetUniformfv, np.float32),
          "m4": (np.arange(16.0).reshape(4, 4) / 7, "f", GL.glGetUniformfv, np.float32),
          "m3": (np.arange(9.0).reshape(3, 3) - 4.5, "f", GL.glGetUniformfv, np.float32)}


@pytest.fixture(scope="module")
def program():
    renderer = SceneRenderer(RenderSettings((8, 8)))  # a current GL context
    program = shaders.compileProgram(shaders.compileShader(VERTEX, GL.GL_VERTEX_SHADER),
                                     shaders.compileShader(FRAGMENT, GL.GL_FRAGMENT_SHADER), validate=False)
    GL.glUseProgram(program)
    yield program
    GL.glUseProgram(0)
    GL.glDeleteProgram(program)
    renderer.close()


@pytest.mark.parametrize("name", list(VALUES))
def test_each_value_reaches_gl_in_the_uniforms_type(program, name):
    value, kind, read, dtype = VALUES[name]
    location = GL.glGetUniformLocation(program, name)
    assert location != -1
    set_uniform_array(location, value, kind)
    got = np.zeros(value.size, dtype)
    read(program, location, got)
    # Matrices go in row major and GL transposes them; read back, they come out column major.
    sent = value.T if value.ndim == 2 else value
    assert got.tobytes() == np.ascontiguousarray(sent, dtype=dtype).tobytes()
    assert GL.glGetError() == GL.GL_NO_ERROR


@pytest.mark.parametrize("value, kind", [(np.zeros(5), "f"), (np.zeros((2, 3)), "f"), (np.zeros(3), "d")])
def test_a_value_gl_has_no_uniform_for_raises(value, kind):
    with pytest.raises(ValueError, match="no GL uniform"):
        set_uniform_array(0, value, kind)
