"""The renderer's shader programs: our GLSL files, their variants, and the cache that links each once.

Every shader is a file of ours in ``shaders/``; none is pyrender's, and nothing patches text:

* ``surface.vert`` / ``surface.frag``: the lit surface (painting and occluders), and with
  ``unlit.frag`` the unlit draws (label, opacity);
* ``depth.vert`` / ``depth.frag``: shadow maps; ``segmentation.frag``: the mask draw;
  ``transmittance.frag``: transparent casters' coloured shadows (``render.transmittance``);
* ``*.glsl``: functions and repeated blocks, pasted where a line reads ``#include "file"``
  (:func:`glsl`).

A program is a pair of files and a set of **defines** (``#define NAME value`` lines after the
``#version`` line, :func:`program_source`): the vertex attributes a mesh has (``NORMAL_LOC``...),
the material's texture, and the variants below, each chosen per draw by ``render.passes`` because a
uniform switch would cost every fragment (quirk 6). :class:`ProgramCache` compiles each (files,
defines) once per context; warm-up compiles every one a config can meet (``sidar_torch.sample.warm_up``).

The quirks the shaders and the cache handle, numbered as the code refers to them:

1. **One cache per context, keyed by files and defines.** pyrender's cache keys on
   ``OpenGL.contextdata.getContext()``, which is a new pointer object at every call on OSMesa, so it
   never hit (thousands of programs and gigabytes after a few thousand renders).
2. **Linked without validation.** PyOpenGL validates a program right after linking, against
   whatever texture units happen to be bound; with shadow maps Mesa reports "active samplers with a
   different type refer to the same texture image unit" for a program that is correct once its
   uniforms are set. A link error still raises.
3. **Shadow lookups dominate the cost of a lit view.** pyrender filtered each shadow map with a 3x3
   grid of manual 4-tap bilinear compares (36 reads per light per pixel, about 50 ms per light at
   512 x 384 on llvmpipe). Spot-light shadow maps here are layers of one depth-compare array
   (``sampler2DArrayShadow``, ``render.shadow_array``) read with 4 hardware-filtered taps at
   +-0.5 texel: a 3 x 3 tent-weighted percentage-closer filter for 4 reads; or, with the define
   ``SIDAR_SHADOW_TAPS`` = 1 (config ``shadow_filter: bilinear``), one tap at the centre: a 2 x 2
   filter; 0 is the soft lookup of quirk 12 (``shaders/spot_shadow.glsl``).
4. **Exact sRGB output.** pyrender encoded with ``pow(x, 1/2.2)`` although it decodes textures with
   the exact curve, so an ambient-only render was up to 9 levels off its texture.
5. **A specular level, a clear coat and a Fresnel opacity.** Nothing here emits light, so the
   material's ``emissive_factor`` uniform carries ``(specular, coat, coat_roughness)``
   (``scene_graph.surface_factors``), and emission is dropped:

   * the dielectric reflectance at normal incidence is ``0.08 * specular`` (pyrender: fixed 4 %);
   * a clear coat adds a second GGX lobe of 4 % reflectance and its own roughness, and the base
     layer below it gets the light the coat does not reflect (``1 - coat * F_coat``);
   * a blended (transparent) surface's opacity rises from its alpha towards 1 with the Schlick
     Fresnel reflectance of the view direction (4 % at normal incidence), and specular light (coat
     and base, unshadowed) raises it too, so a highlight on clear glass shows at full strength. A
     transparent object without an index of refraction is blended over what lies behind it,
     undisplaced; glass (``ior > 1``) is blended in the shader with the refracted painting instead
     (quirk 8). ``unlit.frag`` outputs the same Fresnel opacity, highlights aside, for the
     opacity draw.

6. **Loops cost even when they run zero times.** llvmpipe runs a fragment shader on 8-pixel
   vectors and executes both sides of every branch under a lane mask, uniform conditions
   included: only a loop's trip count saves work. A shadow lookup skipped with a branch was still
   paid in full (the 4 filtered taps per light are two thirds of a lit view). So the spot lights
   run in three loops, in their order: ``[0, lookup_begin)`` without the lookup,
   ``[lookup_begin, lookup_end)`` with it, ``[lookup_end, n_spot_lights)`` without. A lookup that
   cannot find a caster returns exactly "lit" (a factor of 1), so the pixels are the same whichever
   loop adds a light. Occluders draw with the range ``[0, n_shadowed)`` (the shadowed lights come
   first); the painting's draw is split into screen rectangles, each with the narrower range it
   needs (``render.footprints``). A loop that runs no trip is not free either (about 2 ms per
   384 x 512 view per loop left in the shader, 4 ms for the lookup loop), so:

   * a program without spot-light shadows (define ``SPOT_LIGHT_SHADOWS`` absent) adds every light
     in one loop: the same additions in the same order. It draws the views without a shadowed
     light, and the painting's parts whose range is empty (most of its pixels);
   * the painting's program without lookups is a variant per number of light groups up to 4
     (define ``LIGHT_GROUPS``, ``passes.UNROLLED_LIGHT_GROUPS``), which writes the
     groups out with no loop left (left to the compiler's own unrolling, the loop's cost went at 2
     and 3 groups but not at 4 or 8);
   * a group's emitters are counted by products, not loops (quirk 13);
   * the shader has no point or directional light loops (the renderer makes only spot lights;
     pyrender's empty ones cost 13 ms per 512 x 384 view).

7. **Transparent occluders' shadows are coloured.** They go into a transmittance map per shadowed
   spot light instead of its depth map (``render.transmittance``), and the lit shader multiplies
   each shadowed light's contribution by the map's colour where the fragment lies beyond the
   nearest transparent caster: the variant ``TRANSMITTANCE_SHADOWS``, drawn only in views with a
   transparent caster (a uniform switch cost +50 % CPU time per view without one: quirk 6).
8. **The painting in reflective and glass occluders.** The world is black but for the painting (a
   textured rectangle in z = 0) and the occluders, so ``shaders/painting_mirror.glsl`` follows the
   first bounce exactly to the plane z = 0 and samples the painting there (black past its edges or
   going up):

   * **reflection** (variant ``PAINTING_REFLECTION``: opaque materials with a specular layer, see
     ``render.mirror.mirror_define``): ``r = reflect(-v, n)``, weighted by Schlick's Fresnel with
     the material's ``f0`` under a clear coat's 4 % layer, which reflects the same point with its
     own roughness;
   * **refraction** (``PAINTING_REFRACTION``: transparent materials with ``ior > 1``; also
     reflects): Snell's law at the drawn (entry) surface, then at the exit from the occluder's unit
     sphere in its own frame (``object_from_world``), analytic: exact for a sphere or ellipsoid,
     the body's inscribed ellipsoid for other shapes, and a thin plate where the refracted ray
     misses it; total internal reflection at the exit is black. The shader then does quirk 5's
     blend itself, the lit surface over the refracted painting, and writes alpha 1;
   * **the painting's light** at the hit: its albedo times the ambient level plus every spot
     light's unshadowed diffuse irradiance there, times ``painting_diffuse``. Approximated: no
     shadows, none of the painting's own highlights;
   * **roughness as blur**: a mip level from the screen footprint combined in quadrature with the
     disc a cone of half-angle ``roughness^2`` covers where it meets the plane (a trilinear sampler
     object on the painting's unit);
   * not modelled: other occluders in the way of the ray, second bounces, dispersion, caustics.

9. **Shadows as an output.** The variant ``SHADOW_FRACTION`` (the shadow-mask draw of the painting
   alone) accumulates, in the same three light loops, each light's direct irradiance and what of
   it passes the occluders, and outputs ``1 - lit / all`` of their luminances instead of a colour.
10. **The shadow-free colour from the same draw.** The variant ``SHADOW_FREE`` also sums, in the
    same loops and order, every light's contribution before its lookup darkens it, and writes that
    to a second colour output (``layout(location = 1)``): it equals the scene drawn with
    ``shadows: false`` bit for bit (tested).
11. **Blender's spot blend and Cycles' area spread.** Each spot light has a ``smooth_falloff`` member
    (``scene.description.FALLOFFS``): at 1 its falloff is ``smoothstep`` of pyrender's linear ramp in cos
    (``cone_ramp`` in ``shaders/spot_light.glsl``), at 0 pyrender's ramp exactly, at 2 Cycles' spread
    area light, ``cos a (1 - tan a / tan outer)``. A uniform, not a variant.
12. **Soft shadows.** With ``RenderSettings.light_radius`` above 0, ``SIDAR_SHADOW_TAPS`` is 0 and
    ``spot_shadow`` is a percentage-closer soft shadow: 12 raw depth reads of the light's map
    (``spot_shadow_depths``) within ``soft_reach`` of the fragment give the casters' mean depth,
    then 12 depth-compare taps over the penumbra ``light_radius (w - w_b) / (w_b w)`` give the share
    of the light that passes. No caster within reach: exactly lit, as quirk 6 needs. Penumbrae
    measured by rendering are within 0.4 px of ``2 r h / (L - h)`` (``tests/render/test_soft_shadows.py``).
13. **An area light is several emitters, shaded once.** With ``RenderSettings.group_emitters`` the
    emitters of a light are adjacent in the shader's order and form a group: the first of a group
    is shaded once from the group's centre (``spot_light``), and the group adds that shade times
    the sum of its emitters' visibilities (``shaders/group_shade.glsl``). A group of one is shaded
    from the light's own pose, so lights of one emitter give the same bytes either way.
14. **The lights as one uniform block.** The ``spot_lights`` array is a std140 uniform block
    (``SpotLights``) that a pass fills once per layout and every program reads through its binding
    point (``render.light_block``), instead of about 90 uniform calls per program.
15. **The painting supersampled over the pixel's footprint.** With ``SIDAR_TEXTURE_TAPS`` N (the
    texture's define, ``texture_filter: supersampled``: ``gpu.PaintingTexture.defines``), the lit shader
    reads the painting (``painting_texel`` in ``shaders/painting_texel.glsl``) as the mean of N x N
    trilinear lookups on a grid over the pixel's footprint (its texture-space derivatives), each with
    N-times smaller derivatives, so each picks a finer mipmap level: a path tracer's rays through one
    pixel, not one lookup filtered by the footprint's longer side, which blurs an oblique view's
    shorter side. Along each screen axis the grid spans ``clamp(f - 1, 0, 1)`` of the pixel, ``f`` the
    texels per pixel along it: where the view does not shrink the painting (``f <= 1``, view 0) the N x N
    lookups fall on one point and give the one bilinear lookup's value; the label's unlit draw
    reads the texture once, as before.
"""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Any

import numpy as np
from OpenGL import GL
from OpenGL.GL import shaders as gl_shaders

from .light_block import bind_program_block
from .uniforms import set_uniform_array

__all__ = ["SHADER_DIR", "Program", "ProgramCache", "glsl", "program_source"]

SHADER_DIR = Path(__file__).resolve().parent / "shaders"
"""Our GLSL: whole shaders (``*.vert``, ``*.frag``) and the pieces they include (``*.glsl``)."""

_INCLUDE = '#include "'


@functools.cache
def glsl(name: str) -> str:
    """The text of ``shaders/<name>``, each line ``#include "<file>"`` replaced by that file's text (read
    once per process: a renderer's first programs read the same pieces 200 times, 10 ms)."""
    lines = (SHADER_DIR / name).read_text().splitlines(keepends=True)
    return "".join(glsl(line[len(_INCLUDE):].split('"')[0]) if line.startswith(_INCLUDE) else line for line in lines)


def program_source(name: str, defines: dict[str, int]) -> str:
    """The GLSL of our shader ``name`` (a file of ``shaders/``) compiled with ``defines``: each as a
    ``#define NAME value`` line right after the ``#version`` line, in name order."""
    version, rest = glsl(name).split("\n", 1)
    declared = "".join(f"#define {key} {int(value)}\n" for key, value in sorted(defines.items()))
    return f"{version}\n{declared}{rest}"


class Program:
    """One GL program of our shaders, linked at first use, with its uniforms' locations asked of GL once.

    Args:
        shaders: our shader files, vertex then fragment (names in ``shaders/``).
        defines: ``{name: int}``, declared in both stages (:func:`program_source`).
    """

    def __init__(self, shaders: tuple[str, str], defines: dict[str, int]):
        self.shaders = shaders
        self.defines = dict(defines)
        self.id: int | None = None
        """The GL program's name, once linked (else None)."""
        self._locations: dict[str, int] = {}

    def link(self) -> None:
        """Compile and link in the current context, once (quirk 2: without PyOpenGL's validation), and
        point its lights' uniform block at its layout's binding point (``light_block``).

        Raises:
            RuntimeError: a compile or link error (PyOpenGL's message, with the shader's log).
        """
        if self.id is not None:
            return
        stages = (GL.GL_VERTEX_SHADER, GL.GL_FRAGMENT_SHADER)
        shader_ids = [gl_shaders.compileShader(program_source(name, self.defines), stage)
                      for name, stage in zip(self.shaders, stages)]
        vao = GL.glGenVertexArrays(1)
        GL.glBindVertexArray(vao)  # a VAO must be bound while linking (PyOpenGL)
        self.id = gl_shaders.compileProgram(*shader_ids, validate=False)
        GL.glBindVertexArray(0)
        GL.glDeleteVertexArrays(1, [vao])
        bind_program_block(self.id, "SPOT_LIGHT_SHADOWS" in self.defines)

    def use(self) -> None:
        """Make it the current program (linked)."""
        GL.glUseProgram(self.id)

    def set_uniform(self, name: str, value: Any, unsigned: bool = False) -> None:
        """Set a uniform of this (current) program; a name the compiler removed (location -1) is ignored.

        Args:
            name: the uniform's name in the program (``"material.base_color_factor"``).
            value: a Python ``float``/``int``/``bool``, or a 1-D (vector) or 2-D (matrix, row
                major) NumPy array; integer arrays go to ``int`` uniforms, others to ``float``
                (through :func:`~.uniforms.set_uniform_array`).
            unsigned: integers go to ``uint`` uniforms.

        Raises:
            TypeError: a value of a type GL has no uniform for.
        """
        location = self._locations.get(name)
        if location is None:
            location = self._locations[name] = GL.glGetUniformLocation(self.id, name)
        if location == -1:
            return
        if isinstance(value, np.ndarray):
            kind = "u" if unsigned or value.dtype.kind == "u" else "i" if value.dtype.kind == "i" else "f"
            set_uniform_array(location, value, kind)
        elif isinstance(value, (float, np.floating)):
            GL.glUniform1f(location, float(value))
        elif isinstance(value, (int, bool, np.integer)):
            (GL.glUniform1ui if unsigned else GL.glUniform1i)(location, int(value))
        else:
            raise TypeError(f"uniform {name!r}: no GL uniform for a value of type {type(value).__name__}")


class ProgramCache:
    """The programs of one GL context, keyed by shader files and defines (quirk 1): ``len(cache)`` is
    the number of distinct programs, which stays constant over a long run; :attr:`variants` lists
    their defines.

    Args:
        shadow_taps: 4 (3 x 3 tent filter), 1 (2 x 2 filter) or 0 (soft) depth-compare taps per
            shadow lookup: the define ``SIDAR_SHADOW_TAPS`` of every program (quirk 3).
    """

    def __init__(self, shadow_taps: int = 4):
        self._programs: dict[tuple, Program] = {}
        self._common = {"SIDAR_SHADOW_TAPS": shadow_taps}

    def get(self, shaders: tuple[str, str], defines: dict[str, int]) -> Program:
        """The program of ``shaders`` (vertex, fragment: files of ``shaders/``) with ``defines``,
        created at first use (not linked: :meth:`Program.link`)."""
        defines = {**defines, **self._common}
        key = (*shaders, *sorted(defines.items()))
        program = self._programs.get(key)
        if program is None:
            program = self._programs[key] = Program(shaders, defines)
        return program

    @property
    def variants(self) -> list[dict[str, int]]:
        """The defines of every program created so far, in the order they were created."""
        return [program.defines for program in self._programs.values()]

    @property
    def programs(self) -> list[Program]:
        """Every program created so far, in the order they were created."""
        return list(self._programs.values())

    def __len__(self) -> int:
        return len(self._programs)
