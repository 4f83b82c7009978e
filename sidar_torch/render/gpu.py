"""What the renderer uploads to its GL context: meshes (vertex arrays) and the painting's texture.

Both are made from plain arrays and live as long as the context (``SceneRenderer`` destroys it, and
every object with it); nothing here is deleted at garbage collection, which could run while another
renderer's context is current.
"""

from __future__ import annotations

import ctypes

import numpy as np
import trimesh
from OpenGL import GL

from .gl_entry import gl_entry
from .mipmaps import exact_on_cpu, mip_levels

__all__ = ["GpuMesh", "PaintingTexture"]

_FLOAT = 4  # bytes

_DRAW_ELEMENTS = ctypes.CFUNCTYPE(None, ctypes.c_uint, ctypes.c_int, ctypes.c_uint, ctypes.c_void_p, ctypes.c_int)
_DRAW_ARRAYS = ctypes.CFUNCTYPE(None, ctypes.c_uint, ctypes.c_int, ctypes.c_int, ctypes.c_int)
"""``glDrawElementsInstanced(mode, count, type, offset, instances)``, ``glDrawArraysInstanced(mode, first,
count, instances)``."""
_TRIANGLES, _UNSIGNED_INT = int(GL.GL_TRIANGLES), int(GL.GL_UNSIGNED_INT)


class GpuMesh:
    """A triangle mesh in one vertex array: positions, optional normals and texture coordinates,
    interleaved as float32 at attribute locations 0, 1, 2 (those present, in that order), and one
    identity instance matrix at the next four (``INST_M_LOC``; the vertex stage multiplies by it).

    Args:
        positions: ``(N, 3)`` object-frame vertices (any float dtype; stored as float32).
        normals: ``(N, 3)`` or None.
        texcoords: ``(N, 2)`` or None, texture ``(s, t)`` with ``t = 1`` at the image's first row.
        faces: ``(F, 3)`` vertex indices of counter-clockwise triangles, or None: each three
            consecutive vertices are a triangle.

    Attributes:
        bounds: ``(2, 3)`` float64 lower and upper corner of the positions' box (object frame).
        defines: the vertex stage's attribute defines (``NORMAL_LOC``, ``TEXCOORD_0_LOC``, ``INST_M_LOC``).
    """

    def __init__(self, positions: np.ndarray, normals: np.ndarray | None = None, texcoords: np.ndarray | None = None,
                 faces: np.ndarray | None = None):
        self.positions = np.ascontiguousarray(positions, np.float32)
        self.normals = None if normals is None else np.ascontiguousarray(normals, np.float32)
        self.texcoords = None if texcoords is None else np.ascontiguousarray(texcoords, np.float32)
        self.faces = None if faces is None else np.ascontiguousarray(faces, np.uint32)
        self.bounds = np.array([self.positions.min(axis=0), self.positions.max(axis=0)], np.float64)
        self.defines: dict[str, int] = {}
        location = 1
        for name, values in (("NORMAL_LOC", self.normals), ("TEXCOORD_0_LOC", self.texcoords)):
            if values is not None:
                self.defines[name] = location
                location += 1
        self.defines["INST_M_LOC"] = location
        self._vao: int | None = None

    @classmethod
    def from_trimesh(cls, mesh: trimesh.Trimesh, smooth: bool) -> "GpuMesh":
        """``mesh`` with its vertex normals, indexed (``smooth``), or with each face's normal on its
        own three vertices (flat)."""
        if smooth:
            return cls(mesh.vertices, mesh.vertex_normals, faces=mesh.faces)
        return cls(mesh.vertices[mesh.faces].reshape(-1, 3), np.repeat(mesh.face_normals, 3, axis=0))

    def corners(self, pose: np.ndarray) -> np.ndarray:
        """``(8, 3)`` world corners of :attr:`bounds` under the object-to-world ``pose`` ``(4, 4)``."""
        local = trimesh.bounds.corners(self.bounds)
        return pose[:3, :3].dot(local.T).T + pose[:3, 3]

    def upload(self) -> bool:
        """Create the vertex array in the current context, once; returns whether it did."""
        if self._vao is not None:
            return False
        self._vao = GL.glGenVertexArrays(1)
        GL.glBindVertexArray(self._vao)
        columns = [a for a in (self.positions, self.normals, self.texcoords) if a is not None]
        vertices = np.ascontiguousarray(np.hstack(columns).ravel(), np.float32)
        GL.glBindBuffer(GL.GL_ARRAY_BUFFER, GL.glGenBuffers(1))
        GL.glBufferData(GL.GL_ARRAY_BUFFER, vertices.nbytes, vertices, GL.GL_STATIC_DRAW)
        stride, offset = sum(a.shape[1] for a in columns) * _FLOAT, 0
        for location, values in enumerate(columns):
            GL.glVertexAttribPointer(location, values.shape[1], GL.GL_FLOAT, GL.GL_FALSE, stride,
                                     ctypes.c_void_p(offset))
            GL.glEnableVertexAttribArray(location)
            offset += values.shape[1] * _FLOAT
        identity = np.eye(4, dtype=np.float32).ravel()
        GL.glBindBuffer(GL.GL_ARRAY_BUFFER, GL.glGenBuffers(1))
        GL.glBufferData(GL.GL_ARRAY_BUFFER, identity.nbytes, identity, GL.GL_STATIC_DRAW)
        for column in range(4):
            location = self.defines["INST_M_LOC"] + column
            GL.glEnableVertexAttribArray(location)
            GL.glVertexAttribPointer(location, 4, GL.GL_FLOAT, GL.GL_FALSE, 16 * _FLOAT, ctypes.c_void_p(4 * _FLOAT * column))
            GL.glVertexAttribDivisor(location, 1)
        if self.faces is not None:
            GL.glBindBuffer(GL.GL_ELEMENT_ARRAY_BUFFER, GL.glGenBuffers(1))
            GL.glBufferData(GL.GL_ELEMENT_ARRAY_BUFFER, self.faces.nbytes, self.faces, GL.GL_STATIC_DRAW)
        GL.glBindVertexArray(0)
        return True

    def bind(self) -> None:
        """Bind its vertex array (uploaded) for :meth:`draw_bound`."""
        GL.glBindVertexArray(self._vao)

    def draw_bound(self) -> None:
        """Draw every triangle with the bound program and state (the array bound by :meth:`bind`), one
        instance, through ctypes (``gl_entry``: a view draws its meshes dozens of times)."""
        if self.faces is not None:
            gl_entry("glDrawElementsInstanced", _DRAW_ELEMENTS)(_TRIANGLES, self.faces.size, _UNSIGNED_INT, None, 1)
        else:
            gl_entry("glDrawArraysInstanced", _DRAW_ARRAYS)(_TRIANGLES, 0, len(self.positions), 1)

    def draw(self) -> None:
        """Bind, draw every triangle, unbind."""
        self.bind()
        self.draw_bound()
        GL.glBindVertexArray(0)


class PaintingTexture:
    """The painting as an RGBA8 texture with mipmaps, filtered as ``filters`` say.

    Args:
        rgb: ``(H, W, 3)`` uint8 sRGB, row 0 at the top (uploaded flipped: GL's row 0 is the bottom,
            so texture coordinate ``t = 1`` is the image's first row).
        filters: ``(min filter, mag filter, taps)``: GL enums and the lookups per pixel side of the lit
            shader (``scene_graph.PAINTING_FILTERS``, keyed by ``choices.render.TEXTURE_FILTERS``).

    Attributes:
        defines: the defines of the programs that draw it: ``SIDAR_TEXTURE_TAPS`` with ``taps > 1``
            (``programs`` quirk 15), else none.

    The shader decodes sRGB itself; the texture stores the bytes as they are (alpha 255, which GL adds
    to the RGB rows it is given). A renderer keeps one per slot and hands it each new painting of the
    same size (:meth:`replace`): the texture object and its storage are made once and refilled. The
    mipmap levels are made on the CPU, llvmpipe's own bytes (``render.mipmaps``: its blit shader is
    compiled in every process, 61 ms at the first 384x512 painting), or by ``glGenerateMipmap`` for the
    sizes whose levels the CPU would not give exactly. At 384x512 (llvmpipe, one core, load 2) a refill
    with its levels costs 1.35-1.4 ms (1.7 ms by ``glGenerateMipmap``), a new texture 3.7 ms (61 ms).
    """

    def __init__(self, rgb: np.ndarray, filters: tuple[int, int, int]):
        self.rgb = rgb
        self.filters = filters
        self.defines = {"SIDAR_TEXTURE_TAPS": filters[2]} if filters[2] > 1 else {}
        self.id: int | None = None
        self._stale = True  # rgb not in the texture yet

    def replace(self, rgb: np.ndarray) -> None:
        """Hold ``rgb`` instead (the same ``(H, W, 3)``), uploaded into the same texture at the next :meth:`upload`.

        Raises:
            ValueError: ``rgb`` has another shape or dtype.
        """
        if rgb.shape != self.rgb.shape or rgb.dtype != self.rgb.dtype:
            raise ValueError(f"rgb: expected {self.rgb.shape} {self.rgb.dtype} as the texture holds, "
                             f"got {rgb.shape} {rgb.dtype}")
        self.rgb, self._stale = rgb, True

    def upload(self) -> bool:
        """Put :attr:`rgb` and its mipmaps in the texture (created in the current context the first
        time), unless they are there already; returns whether it did."""
        if not self._stale:
            return False
        # Rows of 3 W bytes (the renderer's context unpacks with alignment 1); GL fills alpha with 255.
        rows = np.ascontiguousarray(self.rgb[::-1])
        # Levels 1.. made on the CPU, llvmpipe's bytes (render.mipmaps), where that is exact; else by GL.
        on_cpu = exact_on_cpu(rows.shape[:2])
        levels = [rows, *mip_levels(rows)] if on_cpu else [rows]
        if self.id is None:
            self.id = GL.glGenTextures(1)
            GL.glBindTexture(GL.GL_TEXTURE_2D, self.id)
            for k, level in enumerate(levels):
                GL.glTexImage2D(GL.GL_TEXTURE_2D, k, GL.GL_RGBA8, level.shape[1], level.shape[0], 0, GL.GL_RGB,
                                GL.GL_UNSIGNED_BYTE, level)
            minify, magnify, _ = self.filters
            for name, value in ((GL.GL_TEXTURE_MAG_FILTER, magnify), (GL.GL_TEXTURE_MIN_FILTER, minify),
                                (GL.GL_TEXTURE_WRAP_S, GL.GL_CLAMP_TO_EDGE), (GL.GL_TEXTURE_WRAP_T, GL.GL_CLAMP_TO_EDGE)):
                GL.glTexParameteri(GL.GL_TEXTURE_2D, name, value)
        else:
            GL.glBindTexture(GL.GL_TEXTURE_2D, self.id)
            for k, level in enumerate(levels):
                GL.glTexSubImage2D(GL.GL_TEXTURE_2D, k, 0, 0, level.shape[1], level.shape[0], GL.GL_RGB,
                                   GL.GL_UNSIGNED_BYTE, level)
        if not on_cpu:
            GL.glGenerateMipmap(GL.GL_TEXTURE_2D)
        GL.glBindTexture(GL.GL_TEXTURE_2D, 0)
        self._stale = False
        return True

    def bind(self, unit: int) -> None:
        """Bind to texture unit ``unit``."""
        GL.glActiveTexture(GL.GL_TEXTURE0 + unit)
        GL.glBindTexture(GL.GL_TEXTURE_2D, self.id)

    def delete(self) -> None:
        """Free the texture in the current context (the renderer's, when a painting of another size replaces it)."""
        if self.id is not None:
            GL.glDeleteTextures([self.id])
            self.id, self._stale = None, True
