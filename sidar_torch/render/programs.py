"""Shader programs for pyrender, with three of its quirks fixed in one place.

1. **The program cache never hits on OSMesa.** pyrender keys its cache on
   ``OpenGL.contextdata.getContext()``, which returns a new pointer object at every call on
   OSMesa, so every render compiles, links and leaks fresh programs (thousands of programs and
   gigabytes after a few thousand renders). A cache belongs to one renderer, which owns one
   context, so :class:`ProgramCache` keys on the shaders and defines alone.
2. **Validation fails with shadows.** PyOpenGL validates a program right after linking,
   against whatever texture units happen to be bound; with shadow maps Mesa reports "active
   samplers with a different type refer to the same texture image unit" for a program that
   is correct once its uniforms are set. Programs here are linked without that check (a
   link error still raises).
3. **Shadow lookups dominate the cost of a lit view**: pyrender filters each shadow map with
   a 3x3 grid of manual 4-tap bilinear compares, 36 texture reads per light per pixel (about
   50 ms per light at 512 x 384 on llvmpipe). Spot-light shadow maps here are depth-compare
   samplers (``sampler2DShadow``, set up by the renderer) read with 4 hardware-filtered taps
   at +-0.5 texel: a 3 x 3 tent-weighted percentage-closer filter for 4 reads; or, with the
   program define ``SIDAR_SHADOW_TAPS`` = 1 (config ``shadow_filter: bilinear``), one tap at
   the centre: a 2 x 2 filter.
4. **The lit shader's output encoding is a gamma-2.2 approximation** (``pow(x, 1/2.2)``)
   although it decodes textures with the exact sRGB curve, so an ambient-only render is up to
   9 levels off its texture. :data:`SHADER_PATCHES` swaps in the exact sRGB encoding.
5. **pyrender's material has no specular level, clear coat or Fresnel opacity.** Nothing here
   emits light, so the material's ``emissive_factor`` uniform (always bound by pyrender) carries
   ``(specular, coat, coat_roughness)`` instead (see :func:`surface_factors`), and emission is
   dropped:

   * the dielectric reflectance at normal incidence is ``0.08 * specular`` (pyrender: fixed 4 %);
   * a clear coat adds a second GGX lobe of 4 % reflectance and its own roughness, and the base
     layer below it gets the light the coat does not reflect (``1 - coat * F_coat``);
   * a blended (transparent) surface's opacity rises from its alpha towards 1 with the Schlick
     Fresnel reflectance of the view direction (4 % at normal incidence), so glass reads darker
     or brighter at its silhouette, and specular light (coat and base, unshadowed) raises the
     opacity too, so a highlight on clear glass shows at full strength instead of being blended
     away. There is no refraction: what lies behind a transparent object is seen undisplaced.
     The unlit shader (``flat.frag``) outputs the same Fresnel opacity, highlights aside, for
     the renderer's opacity draw.

6. **Loops cost even when they run zero times.** llvmpipe runs a fragment shader on 8-pixel
   vectors and executes both sides of every branch under a lane mask, uniform conditions
   included: only a loop's trip count saves work. pyrender's empty point- and
   directional-light loops cost 13 ms per 512 x 384 view (the renderer makes only spot lights),
   and a shadow lookup skipped with a branch (``i >= n_shadowed ? 0.0 : lookup``) was still
   paid in full: the 4 filtered taps per light are two thirds of a lit view. So the point and
   directional loops are compiled out, and the spot lights run in two loops: the first
   ``n_shadowed_spot_lights`` with their shadow lookup, the rest without (the renderer orders
   the lights so; the sum runs in the same order, so the pixels are the same either way).

7. **Transparent occluders cast shadows as dark as opaque ones** in pyrender. Here they go into a
   transmittance map per shadowed spot light instead of its depth map (model and limits in
   ``render.transmittance``; :data:`SHADER_SOURCES` holds the shader that draws them), and the
   lit shader multiplies each shadowed light's contribution by the map's colour where the
   fragment lies beyond the nearest transparent caster (4 texels, a distance test per texel,
   bilinear weights; the maps are tiles of one 2-D texture on one texture unit). The lookup is a
   program variant (define ``TRANSMITTANCE_SHADOWS``, chosen by :class:`ProgramCache`) drawn
   only in views with a transparent caster; other views run the shader without it, as before
   (a uniform switch cost +50 % CPU time per view without any transparent caster: quirk 6).

Shader sources stay pyrender's own; each patch names the exact text it replaces and fails
loudly if a pyrender release changes it.
"""

from __future__ import annotations

import os

import numpy as np
from OpenGL import GL
from OpenGL.GL import shaders as gl_shaders
from pyrender.shader_program import ShaderProgram, ShaderProgramCache

__all__ = ["ProgramCache", "SHADER_PATCHES", "SHADER_SOURCES", "surface_factors"]

_SPOT_SHADOW_LOOKUP = """
uniform int n_shadowed_spot_lights;

float spot_shadow(mat4 light_matrix, sampler2DShadow shadow_map, float nl)
{
    vec4 proj_coords = light_matrix * vec4(frag_position.xyz, 1.0);
    vec3 light_coords = proj_coords.xyz / proj_coords.w * 0.5 + 0.5;
    if (light_coords.z > 1.0) {
        return 0.0;
    }
    float compare = light_coords.z - max(0.001 * (1.0 - nl), 0.0001) / proj_coords.w;
#if SIDAR_SHADOW_TAPS == 1
    float lit = 4.0 * texture(shadow_map, vec3(light_coords.xy, compare));
#else
    vec2 texel = 0.5 / vec2(textureSize(shadow_map, 0));
    float lit = texture(shadow_map, vec3(light_coords.xy + vec2(-texel.x, -texel.y), compare))
              + texture(shadow_map, vec3(light_coords.xy + vec2(texel.x, -texel.y), compare))
              + texture(shadow_map, vec3(light_coords.xy + vec2(-texel.x, texel.y), compare))
              + texture(shadow_map, vec3(light_coords.xy + vec2(texel.x, texel.y), compare));
#endif
    return 1.0 - 0.25 * lit;
}

#ifdef TRANSMITTANCE_SHADOWS
uniform sampler2D transmittance_maps;  // spot light k's tile: transmittance (rgb), nearest caster w (a)
uniform ivec2 transmittance_layout;    // (tile side in texels, tiles per column)

vec3 spot_transmittance(mat4 light_matrix, int k)
{
    // Bilinear filter of light k's transmittance over the 4 nearest texels, each counted only where
    // this fragment lies beyond that texel's nearest transparent caster (0.2 % margin: float16).
    vec4 proj_coords = light_matrix * vec4(frag_position.xyz, 1.0);
    int tile = transmittance_layout.x;
    ivec2 origin = tile * ivec2(k / transmittance_layout.y, k % transmittance_layout.y);
    vec2 st = (proj_coords.xy / proj_coords.w * 0.5 + 0.5) * float(tile) - 0.5;
    ivec2 corner = ivec2(floor(st));
    vec2 f = st - floor(st);
    float depth = proj_coords.w * 0.998;
    vec3 absorbed = vec3(0.0);
    for (int j = 0; j < 4; j++) {
        ivec2 offset = ivec2(j & 1, j >> 1);
        vec4 texel = texelFetch(transmittance_maps, origin + clamp(corner + offset, ivec2(0), ivec2(tile - 1)), 0);
        vec2 weight = mix(1.0 - f, f, vec2(offset));
        absorbed += (depth > texel.a ? weight.x * weight.y : 0.0) * (1.0 - texel.rgb);
    }
    return 1.0 - absorbed;  // exactly 1 where no caster lies between the light and the fragment
}
#endif
"""

_SPOT_LIGHT = """
vec3 spot_light(int i, vec3 n, float roughness, float metallic, vec3 f0, vec3 c_diff, vec3 albedo,
                out vec3 l)
{
    // pyrender's spot-light loop body, without the shadow: light i's reflected radiance.
    vec3 position = spot_lights[i].position;
    vec3 v = normalize(cam_pos - frag_position); // Vector towards camera
    l = normalize(position - frag_position); // Vector towards light
    vec3 direction = spot_lights[i].direction;
    float las = spot_lights[i].light_angle_scale;
    float lao = spot_lights[i].light_angle_offset;
    float dist = length(position - frag_position);
    float cd = clamp(dot(direction, -l), 0.0, 1.0);
    float attenuation = clamp(cd * las + lao, 0.0, 1.0);
    attenuation = attenuation * attenuation * spot_lights[i].intensity;
    attenuation = attenuation / (dist * dist);
    vec3 radiance = attenuation * spot_lights[i].color;
    return compute_brdf(n, v, l, roughness, metallic, f0, c_diff, albedo, radiance);
}
"""

_PYRENDER_SPOT_LOOP_HEAD = """    for (int i = 0; i < n_spot_lights; i++) {
        vec3 position = spot_lights[i].position;
        vec3 v = normalize(cam_pos - frag_position); // Vector towards camera
        vec3 l = normalize(position - frag_position); // Vector towards light

        // Compute attenuation and radiance
        vec3 direction = spot_lights[i].direction;
        float las = spot_lights[i].light_angle_scale;
        float lao = spot_lights[i].light_angle_offset;
        float dist = length(position - frag_position);
        float cd = clamp(dot(direction, -l), 0.0, 1.0);
        float attenuation = clamp(cd * las + lao, 0.0, 1.0);
        attenuation = attenuation * attenuation * spot_lights[i].intensity;
        attenuation = attenuation / (dist * dist);
        vec3 radiance = attenuation * spot_lights[i].color;

        // Compute outbound color
        vec3 res = compute_brdf(n, v, l, roughness, metallic,
                                f0, c_diff, base_color.rgb, radiance);
"""

_SHADOWED_SPOT_LOOP_HEAD = """    for (int i = 0; i < n_shadowed_spot_lights; i++) {  // lights with a shadow lookup
        vec3 l;
        vec3 res = spot_light(i, n, roughness, metallic, f0, c_diff, base_color.rgb, l);
"""

_UNSHADOWED_SPOT_LOOP = """        color.xyz += res;
    }
    for (int i = n_shadowed_spot_lights; i < n_spot_lights; i++) {  // the others: no lookup
        vec3 l;
        color.xyz += spot_light(i, n, roughness, metallic, f0, c_diff, base_color.rgb, l);
    }
    color.xyz += base_color.xyz * ambient_light;"""

_FRESNEL_OPACITY = """
float fresnel_opacity(float alpha, float cos_angle)
{
    // A blended surface's opacity, raised towards 1 by the Schlick-Fresnel reflectance (4 % head-on).
    float fresnel = 0.04 + 0.96 * pow(1.0 - cos_angle, 5.0);
    return mix(alpha, 1.0, fresnel);
}
"""

_TRANSMITTANCE_FRAG = """#version 330 core
// One transparent caster's transmittance seen from a spot light (see render.transmittance).
uniform vec4 base_color;      // the caster's linear RGBA base colour
uniform vec3 light_position;  // world frame
in vec3 frag_position;        // world frame
in vec3 frag_normal;
out vec4 frag_color;
""" + _FRESNEL_OPACITY + """
void main()
{
    float nl = clamp(abs(dot(normalize(frag_normal), normalize(light_position - frag_position))), 0.0, 1.0);
    vec3 tint = base_color.rgb / max(max(base_color.r, max(base_color.g, base_color.b)), 1e-6);
    frag_color = vec4((1.0 - fresnel_opacity(base_color.a, nl)) * tint, 1.0 / gl_FragCoord.w);
}
"""

PATCH_DEFINES = ("TRANSMITTANCE_SHADOWS",)
"""Program defines that :data:`SHADER_PATCHES` test with ``#ifdef`` (passed to GLSL as ``#define``)."""

SHADER_SOURCES: dict[str, str] = {"transmittance.frag": _TRANSMITTANCE_FRAG}
"""Shaders of our own, by file name (pair them with pyrender's ``mesh.vert``); no ``#ifdef``."""

_SURFACE_BRDF = """
        vec3 spec_contrib = F * G * D / (4.0 * nl * nv + 0.001);

        // Clear coat: a GGX lobe of 4 % reflectance and roughness material.emissive_factor.z.
        float coat = material.emissive_factor.y;
        PBRInfo coat_info = PBRInfo(nl, nv, nh, lh, vh, max(material.emissive_factor.z, min_roughness),
                                    0.0, vec3(0.04), vec3(0.0));
        float coat_f = specular_reflection(coat_info).x * coat;
        float coat_spec = coat_f * geometric_occlusion(coat_info) * microfacet_distribution(coat_info)
                        / (4.0 * nl * nv + 0.001);
        specular_light += nl * radiance * (spec_contrib + coat_spec);

        vec3 color = nl * radiance * ((diffuse_contrib + spec_contrib) * (1.0 - coat_f) + coat_spec);
"""

_SURFACE_GLOBALS = """
vec3 specular_light = vec3(0.0);  // specular light reflected towards the camera, unshadowed

vec3 compute_brdf("""

_FRESNEL_ALPHA = """vec4(linear_to_srgb(color.xyz), surface_alpha(base_color.a, n))"""

_EXACT_SRGB_ENCODE = _FRESNEL_OPACITY + """
float surface_alpha(float alpha, vec3 n)
{
    // Opacity of a blended surface: Schlick-Fresnel towards grazing views, plus its specular light.
    float nv = clamp(abs(dot(n, normalize(cam_pos - frag_position))), 0.0, 1.0);
    return clamp(fresnel_opacity(alpha, nv) + max(specular_light.r, max(specular_light.g, specular_light.b)),
                 0.0, 1.0);
}

vec3 linear_to_srgb(vec3 c)
{
    c = clamp(c + max(max(c.r, max(c.g, c.b)) - 1.0, 0.0), 0.0, 1.0);  // over-exposure spills into white
    return mix(c * 12.92, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, step(vec3(0.0031308), c));
}

void main()
"""

SHADER_PATCHES: dict[str, list[tuple[str, str]]] = {
    "mesh.frag": [
        ("sampler2D shadow_map;\n    mat4 light_matrix;\n    #endif\n};\n\nstruct DirectionalLight",
         "sampler2DShadow shadow_map;\n    mat4 light_matrix;\n    #endif\n};\n\nstruct DirectionalLight"),
        ("float shadow = shadow_calc(\n            spot_lights[i].light_matrix,",
         "float shadow = spot_shadow(\n            spot_lights[i].light_matrix,"),
        # Only the first n_shadowed_spot_lights lights can shadow what the camera sees: the others
        # run in a second loop without the lookup, which would return "lit" (quirk 6).
        (_PYRENDER_SPOT_LOOP_HEAD, _SHADOWED_SPOT_LOOP_HEAD),
        ("        color.xyz += res;\n    }\n    color.xyz += base_color.xyz * ambient_light;", _UNSHADOWED_SPOT_LOOP),
        ("for (int i = 0; i < n_directional_lights; i++) {", "for (int i = 0; i < 0; i++) {  // none (quirk 6)"),
        ("for (int i = 0; i < n_point_lights; i++) {", "for (int i = 0; i < 0; i++) {  // none (quirk 6)"),
        ("\nvoid main()\n", _SPOT_SHADOW_LOOKUP + _SPOT_LIGHT + _EXACT_SRGB_ENCODE),
        ("            spot_lights[i].shadow_map,\n            nl\n        );\n        res = res * (1.0 - shadow);\n",
         "            spot_lights[i].shadow_map,\n            nl\n        );\n        res = res * (1.0 - shadow);\n"
         "#ifdef TRANSMITTANCE_SHADOWS\n"
         "        res *= spot_transmittance(spot_lights[i].light_matrix, i);  // in the shadowed loop only\n"
         "#endif\n"),
        ("vec4(pow(color.xyz, vec3(1.0/2.2)), color.a * base_color.a)", _FRESNEL_ALPHA),
        ("\nvec3 compute_brdf(", _SURFACE_GLOBALS),
        ("""
        vec3 spec_contrib = F * G * D / (4.0 * nl * nv + 0.001);

        vec3 color = nl * radiance * (diffuse_contrib + spec_contrib);
""", _SURFACE_BRDF),
        ("vec3 dialectric_spec = vec3(min_roughness);", "vec3 dialectric_spec = vec3(0.08 * material.emissive_factor.x);"),
        ("    color.xyz += emissive * material.emissive_factor;\n", ""),
    ],
    # The unlit draws (label, opacity) output the Fresnel opacity of the lit draw, highlights aside.
    "flat.frag": [
        ("\nvoid main()\n", _FRESNEL_OPACITY + "\nvoid main()\n"),
        ("frag_color = clamp(base_color, 0.0, 1.0);",
         "frag_color = vec4(clamp(base_color.rgb, 0.0, 1.0), fresnel_opacity(base_color.a, "
         "clamp(abs(dot(normalize(frag_normal), normalize(cam_pos - frag_position))), 0.0, 1.0)));"),
    ],
}
"""Per shader file, ``(old, new)`` text replacements, applied after pyrender has resolved the
``#ifdef`` lines (so no pattern may contain one)."""


def surface_factors(specular: float, coat: float, coat_roughness: float) -> np.ndarray:
    """The ``(3,)`` float32 value of a material's ``emissiveFactor`` that the patched shader reads as
    specular level, clear-coat weight and clear-coat roughness (all in [0, 1]; see quirk 5)."""
    return np.array([specular, coat, coat_roughness], dtype=np.float32)


class _PatchedProgram(ShaderProgram):
    """A pyrender shader program built from patched sources and linked without validation."""

    def _load(self, shader_filename: str) -> str:
        if os.path.basename(shader_filename) in SHADER_SOURCES:
            return SHADER_SOURCES[os.path.basename(shader_filename)]
        text = super()._load(shader_filename)
        for old, new in SHADER_PATCHES.get(os.path.basename(shader_filename), []):
            if text.count(old) != 1:
                raise RuntimeError(f"pyrender shader {shader_filename!r} changed: cannot patch {old.strip()!r}")
            text = text.replace(old, new)
        for name, value in self.defines.items():  # pyrender substituted its own before the patches
            if name.startswith("SIDAR_"):
                text = text.replace(name, str(value))
        # pyrender resolved its own #ifdef lines before the patches went in; GLSL resolves ours.
        version, rest = text.split("\n", 1)
        defined = "".join(f"#define {name} 1\n" for name in PATCH_DEFINES if name in self.defines)
        return f"{version}\n{defined}{rest}"

    def _add_to_context(self) -> None:
        if self._program_id is not None:
            raise ValueError("Shader program already in context")
        stages = [(self.vertex_shader, GL.GL_VERTEX_SHADER), (self.fragment_shader, GL.GL_FRAGMENT_SHADER),
                  (self.geometry_shader, GL.GL_GEOMETRY_SHADER)]
        shader_ids = [gl_shaders.compileShader(self._load(path), kind) for path, kind in stages if path]
        self._vao_id = GL.glGenVertexArrays(1)
        GL.glBindVertexArray(self._vao_id)  # a VAO must be bound while linking (PyOpenGL)
        self._program_id = gl_shaders.compileProgram(*shader_ids, validate=False)
        GL.glBindVertexArray(0)


class ProgramCache(ShaderProgramCache):
    """pyrender's program cache for a single GL context: keyed by shader files and defines only.

    ``len(cache)`` is the number of distinct programs built, which stays constant over a long run.

    While :attr:`transmittance` is true, lit programs with spot-light shadows are the variant
    that also reads the transmittance maps (define ``TRANSMITTANCE_SHADOWS``, quirk 7).

    Args:
        shadow_taps: 4 (3 x 3 tent filter) or 1 (2 x 2 filter) depth-compare taps per shadow lookup.
    """

    def __init__(self, shadow_taps: int = 4):
        super().__init__()
        self._extra_defines = {"SIDAR_SHADOW_TAPS": shadow_taps}
        self.transmittance = False

    def get_program(self, vertex_shader, fragment_shader, geometry_shader=None, defines=None):
        defines = {**(defines or {}), **self._extra_defines}
        if self.transmittance and fragment_shader == "mesh.frag" and "SPOT_LIGHT_SHADOWS" in defines:
            defines["TRANSMITTANCE_SHADOWS"] = 1
        names = tuple(os.path.basename(s) for s in (vertex_shader, fragment_shader, geometry_shader) if s)
        key = names + tuple(sorted(defines.items()))
        if key not in self._program_cache:
            paths = [os.path.join(self.shader_dir, s) if s else None
                     for s in (vertex_shader, fragment_shader, geometry_shader)]
            self._program_cache[key] = _PatchedProgram(*paths, defines=defines)
        return self._program_cache[key]

    def __len__(self) -> int:
        return len(self._program_cache)
