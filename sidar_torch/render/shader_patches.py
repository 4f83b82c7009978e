"""pyrender's shaders, patched: the patch table, our GLSL in ``shaders/``, and the quirks they fix.

The program classes that load them (quirks 1 and 2) are in ``render.pyrender_overrides``, with every other
pyrender override.

1. **The program cache never hits on OSMesa.** pyrender keys its cache on
   ``OpenGL.contextdata.getContext()``, which returns a new pointer object at every call on
   OSMesa, so every render compiles, links and leaks fresh programs (thousands of programs and
   gigabytes after a few thousand renders). A cache belongs to one renderer, which owns one
   context, so ``pyrender_overrides.ProgramCache`` keys on the shaders and defines alone.
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
   the centre: a 2 x 2 filter; 0 is the soft lookup of quirk 12.
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
     away. A transparent object without an index of refraction is blended over what lies behind
     it, undisplaced; glass (``ior > 1``) is blended in the shader with the refracted painting
     instead (quirk 8).
     The unlit shader (``flat.frag``) outputs the same Fresnel opacity, highlights aside, for
     the renderer's opacity draw.

6. **Loops cost even when they run zero times.** llvmpipe runs a fragment shader on 8-pixel
   vectors and executes both sides of every branch under a lane mask, uniform conditions
   included: only a loop's trip count saves work. pyrender's empty point- and
   directional-light loops cost 13 ms per 512 x 384 view (the renderer makes only spot lights),
   and a shadow lookup skipped with a branch (``i >= n_shadowed ? 0.0 : lookup``, or an ``if`` on a
   uniform bit mask) was still paid in full: the 4 filtered taps per light are two thirds of a lit
   view. So the point and directional loops are compiled out, and the spot lights run in three
   loops, in their order: ``[0, lookup_begin)`` without the lookup, ``[lookup_begin, lookup_end)``
   with it, ``[lookup_end, n_spot_lights)`` without. A lookup that cannot find a caster returns
   exactly "lit" (a factor of 1), so the pixels are the same whichever loop adds a light. Occluders
   draw with the range ``[0, n_shadowed)`` (the renderer puts the shadowed lights first); the
   painting's draw is split into screen rectangles, each with the narrower range it needs
   (``render.footprints``).
   A loop that runs no trip is not free either: on a painting with no light, each loop left in the
   shader costs about 2 ms per 384 x 512 view, and the lookup loop about 4 ms in lit views, paid by
   every fragment the program draws (measured by editing the shader). So:

   * a program without spot-light shadows (pyrender's define ``SPOT_LIGHT_SHADOWS`` absent) adds
     every light in one loop instead of three around an empty range: the same additions in the same
     order. It draws the views without a shadowed light, and the painting's parts whose range is
     empty (most of its pixels; ``GLRenderer._draw_parts``);
   * the painting's program without lookups is a variant per number of light groups up to 4 (define
     ``LIGHT_GROUPS``, ``pyrender_overrides.UNROLLED_LIGHT_GROUPS``), which writes the groups out, one
     after the other, with no loop left (left to the compiler's own unrolling, the loop's cost went
     at 2 and 3 groups but not at 4 or 8); warm-up compiles every count a config can draw
     (``sidar_torch.warm_up``);
   * a group's emitters are counted by products, not loops (quirk 13).

7. **Transparent occluders cast shadows as dark as opaque ones** in pyrender. Here they go into a
   transmittance map per shadowed spot light instead of its depth map (model and limits in
   ``render.transmittance``; ``shaders/transmittance.frag`` draws them), and the
   lit shader multiplies each shadowed light's contribution by the map's colour where the
   fragment lies beyond the nearest transparent caster (4 texels, a distance test per texel,
   bilinear weights; the maps are tiles of one 2-D texture on one texture unit). The lookup is a
   program variant (define ``TRANSMITTANCE_SHADOWS``, chosen by ``pyrender_overrides.ProgramCache``) drawn
   only in views with a transparent caster; other views run the shader without it, as before
   (a uniform switch cost +50 % CPU time per view without any transparent caster: quirk 6).

8. **pyrender reflects and refracts nothing**, but the world here is black except the painting (a
   textured rectangle in z = 0) and the occluders, so what a ray leaving an occluder meets is
   almost always the painting or nothing. ``shaders/painting_mirror.glsl`` follows the first
   bounce exactly to the plane z = 0 and samples the painting there (black past its edges or
   going up):

   * **reflection** (program define ``PAINTING_REFLECTION``: opaque materials with a specular layer,
     i.e. metallic, a specular level or a clear coat; see ``render.mirror.mirror_define``):
     ``r = reflect(-v, n)``, weighted by Schlick's Fresnel with the material's ``f0`` (dielectric
     ``0.08 * specular``, metal its base colour) under a clear coat's 4 % layer, which reflects
     the same point with its own roughness;
   * **refraction** (``PAINTING_REFRACTION``: transparent materials with ``ior > 1``, i.e. glass;
     also reflects): Snell's law at the drawn (entry) surface, then at the exit from the
     occluder's unit sphere in its own frame (``object_from_world``, the inverse pose), analytic:
     exact for a sphere or ellipsoid, the body's inscribed ellipsoid for other shapes, and a thin
     plate (exit parallel to the entry face, an undeviated ray) where the refracted ray misses it;
     total internal reflection at the exit is black. Two interfaces because the exit bends the ray
     again (one interface, the ray continuing inside the glass down to the plane, moves the painting
     15 % less at the test's points: 7.1-7.9 instead of 8.3-9.3 texels for a sphere of radius 0.15
     and index 1.5 at 0.2 above it), and an analytic exit costs one quadratic. The shader then does
     quirk 5's blend itself, the lit surface over the refracted painting with the same Fresnel
     opacity, and writes alpha 1;
   * **the painting's light** at the hit: its albedo (the texture, sRGB-decoded) times the ambient
     level plus every spot light's unshadowed diffuse irradiance there, cone and distance falloff
     exact, times ``painting_diffuse`` (the painting material's diffuse factor at normal incidence).
     Approximated: no shadows, and none of the painting's own specular highlights;
   * **roughness as blur**: a mip level (``textureLod``; pyrender builds the painting's mipmaps,
     and a trilinear sampler object on its unit gives the blur even when the painting is drawn
     bilinear), from the screen footprint (``dFdx``/``dFdy`` of the texture coordinates) combined in
     quadrature with the disc a cone of half-angle ``roughness^2`` (GGX alpha) covers where it
     meets the plane;
   * not modelled: other occluders (or the occluder itself) in the way of the ray, second bounces,
     dispersion, caustics; the painting reflects nothing of itself (it is a plane), so its
     reflective materials need nothing here.

   Cost, per fragment of such an occluder only: one plane intersection, one loop over the spot
   lights (no texture reads) and two ``textureLod`` reads per traced ray; glass traces two rays.
   They are program variants chosen per primitive by ``pyrender_overrides.ProgramCache`` (quirk 6: a uniform
   switch would be paid by every fragment), so the painting and other materials run the programs
   they did before, pixel for pixel.

9. **pyrender knows nothing of shadows as an output.** The program variant ``SHADOW_FRACTION``
   (``render.renderer``'s shadow-mask draw of the painting alone) accumulates, in the same three
   light loops, each light's direct irradiance (``spot_irradiance``: cone and distance falloff
   times ``n . l``, per channel) and what of it passes the occluders (the lookup's ``1 - shadow``
   times the transmittance, per channel), and outputs ``1 - lit / all`` of their luminances
   instead of a colour (``shaders/shadow_fraction_*.glsl``). The colour it would compute is dead
   code the compiler removes; lights outside the lookup range pass whole, as in the colour pass.
10. **pyrender draws one colour per fragment.** The program variant ``SHADOW_FREE`` (the colour
    pass of a renderer with ``shadow_free``) also sums, in the same three light loops and in the same
    order, every light's contribution before its lookup darkens it, adds the ambient light and the
    painting seen in a mirror or through glass as the colour does, and writes that to a second
    colour output (``layout(location = 1)``, the framebuffer's second attachment) with the same
    opacity: the view with no light blocked, from the same draw. The additions are the ones a
    draw without lookups makes, in its order, so it equals the scene drawn with ``shadows: false``
    bit for bit (tested).
11. **pyrender's spot lights fade quadratically between their cones.** Each spot light gets a
    ``smooth_falloff`` member; at 1 its falloff is Blender's spot blend, ``smoothstep`` of pyrender's
    linear ramp in cos (``cone_ramp`` in ``shaders/spot_light.glsl`` returns its square root, so the
    callers square it as before; at 0 it returns pyrender's ramp exactly). A uniform, not a variant:
    one compiled program serves both.
12. **pyrender's shadows are hard.** With ``RenderSettings.light_radius`` above 0 the program
    define ``SIDAR_SHADOW_TAPS`` is 0 and ``spot_shadow`` is a percentage-closer soft shadow
    (``soft_shadow`` in ``shaders/spot_shadow.glsl``): 12 raw depth reads of the light's map (the
    same texture through a sampler without comparison, ``spot_shadow_depths``) within
    ``soft_reach`` of the fragment (``plan.soft_reach``: the widest penumbra any of the view's
    occluders can throw) give the casters' mean depth ``w_b`` along the light's axis (window depth
    turned back through the projection's ``P[2][2]``, ``P[2][3]``), then 12 depth-compare taps over
    the penumbra ``light_radius (w - w_b) / (w_b w)`` (tangent units, times ``P[0][0] / 2`` and
    ``P[1][1] / 2`` in texture units) give the share of the light that passes. No caster within
    reach: exactly lit, as quirk 6 needs; the plan widens every lookup margin (footprints, idle
    lights, culling) and each fitted frustum by the same reach. Penumbrae measured by rendering
    are within 0.4 px of ``2 r h / (L - h)`` (``tests/render/test_soft_shadows.py``).

13. **An area light is several emitters, each shaded.** A light of ``S`` emitters (an area light's
    samples) costs ``S`` evaluations of the surface's two GGX lobes per fragment, about 1.5 ms each per
    384 x 512 view on llvmpipe, and shows ``S`` highlights where a real one shows one. With
    ``RenderSettings.group_emitters`` (config ``area_light_shading: per_light``) the emitters of a light
    are adjacent in the shader's order and form a group: each spot light has ``group_size``,
    ``group_position`` and ``group_direction`` members, the first of a group is shaded once from the
    group's centre (``spot_light``; ``spot_irradiance`` alike), and the group adds that shade times the
    sum of its emitters' visibilities, each its own lookup times its transmittance (exactly 1 where
    lit), or times its number of emitters where it has no lookup (``shaders/group_shade.glsl``, in
    every loop). A group of one is shaded from the light's own pose, so lights of one emitter give the
    same bytes either way. ``render.plan`` shadows a light's emitters all or none and widens the footprints'
    lookup ranges to whole lights (``plan.whole_lights``).
14. **pyrender sets every member of every light as a uniform, in every program.** About 90 calls per
    program and three programs per lit pass, 0.5 ms of a 192 x 256 view. The ``spot_lights`` array is
    a std140 uniform block here (``SpotLights``), which a pass fills once per layout and every program
    reads through its binding point (``render.light_block``).

Shader sources stay pyrender's own; each patch names the exact text it replaces and fails
loudly if a pyrender release changes it. The GLSL we add lives in ``shaders/`` (``*.glsl`` pieces,
``#include "file"`` lines expanded by :func:`glsl`; ``*.frag`` whole shaders of our own;
``pyrender_*.glsl`` quotes pyrender's text that a patch replaces).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..render_choices import MAX_SHADOWED_LIGHTS
from .light_block import BLOCK_NAME

__all__ = ["PATCH_DEFINES", "SHADER_DIR", "SHADER_PATCHES", "SHADER_SOURCES", "glsl", "patch_source", "surface_factors"]

SHADER_DIR = Path(__file__).resolve().parent / "shaders"
"""Our GLSL: whole shaders (``*.frag``) and the pieces the patches put into pyrender's (``*.glsl``)."""

_INCLUDE = '#include "'


def glsl(name: str) -> str:
    """The text of ``shaders/<name>``, each line ``#include "<file>"`` replaced by that file's text."""
    lines = (SHADER_DIR / name).read_text().splitlines(keepends=True)
    return "".join(glsl(line[len(_INCLUDE):].split('"')[0]) if line.startswith(_INCLUDE) else line for line in lines)


def _before(anchor: str, *names: str) -> tuple[str, str]:
    """A patch putting the files ``names`` in front of the text ``anchor``."""
    return anchor, "".join(glsl(name) for name in names) + anchor


def _after(anchor: str, text: str) -> tuple[str, str]:
    """A patch putting ``text`` after the text ``anchor``."""
    return anchor, anchor + text


PATCH_DEFINES = ("TRANSMITTANCE_SHADOWS", "PAINTING_REFLECTION", "PAINTING_REFRACTION", "SHADOW_FRACTION",
                 "SHADOW_FREE", "SPOT_LIGHT_SHADOWS", "LIGHT_GROUPS")
"""Program defines that :data:`SHADER_PATCHES` test with ``#ifdef`` or ``#if`` (passed to GLSL as
``#define NAME value``; ``SPOT_LIGHT_SHADOWS`` is pyrender's, whose own ``#ifdef`` lines it resolves
itself)."""

SHADER_SOURCES = ("transmittance.frag",)
"""Shaders of our own in ``shaders/`` (pair them with pyrender's ``mesh.vert``); no ``#ifdef``."""

_MAIN = "\nvoid main()\n"

SHADER_PATCHES: dict[str, list[tuple[str, str]]] = {
    "mesh.frag": [
        # Quirk 3: spot-light shadow maps are layers of one depth-compare array, read by spot_shadow.
        ("sampler2D shadow_map;\n    mat4 light_matrix;\n    #endif\n};\n\nstruct DirectionalLight",
         "int shadow_layer;\n    mat4 light_matrix;\n    #endif\n};\n\nstruct DirectionalLight"),
        # Quirk 14: the lights as one uniform block (pyrender substituted MAX_SPOT_LIGHTS).
        (f"uniform SpotLight spot_lights[{MAX_SHADOWED_LIGHTS}];",
         f"layout(std140) uniform {BLOCK_NAME} {{\n    SpotLight spot_lights[{MAX_SHADOWED_LIGHTS}];\n}};"),
        # Quirk 11: Blender's spot blend, per light (spot_light.glsl's cone_ramp).
        ("    float light_angle_offset;\n",
         "    float light_angle_offset;\n    float smooth_falloff;\n    vec4 soft_depth;\n    float soft_reach;\n"
         "    vec3 group_position;\n    vec3 group_direction;\n    int group_size;\n"),
        ("float shadow = shadow_calc(\n            spot_lights[i].light_matrix,\n            spot_lights[i].shadow_map,",
         "float shadow = spot_shadow(i,\n            spot_lights[i].light_matrix,\n            spot_lights[i].shadow_layer,"),
        # Quirk 6: only the lights in [lookup_begin, lookup_end) may find a caster where this draw
        # shades: the others run in loops without the lookup, which would return "lit".
        (glsl("pyrender_spot_loop_head.glsl"), glsl("shadowed_spot_loop_head.glsl")),
        ("        color.xyz += res;\n    }\n    color.xyz += base_color.xyz * ambient_light;",
         glsl("unshadowed_spot_loop.glsl")),
        ("for (int i = 0; i < n_directional_lights; i++) {", "for (int i = 0; i < 0; i++) {  // none (quirk 6)"),
        ("for (int i = 0; i < n_point_lights; i++) {", "for (int i = 0; i < 0; i++) {  // none (quirk 6)"),
        _before(_MAIN, "spot_shadow.glsl", "spot_light.glsl", "surface_output.glsl"),
        # Quirk 7: coloured shadows of transparent casters, in the shadowed loop only.
        _after("            spot_lights[i].shadow_layer,\n            nl\n        );\n"
               "        res = res * (1.0 - shadow);\n",
               "#ifdef TRANSMITTANCE_SHADOWS\n"
               "        res *= spot_transmittance(spot_lights[i].light_matrix, i);  // in the shadowed loop only\n"
               "#endif\n" + glsl("shadow_fraction_lookup.glsl")),
        # Quirks 4 and 5: exact sRGB output, Fresnel and specular opacity, clear coat, specular level.
        ("vec4(pow(color.xyz, vec3(1.0/2.2)), color.a * base_color.a)",
         "vec4(linear_to_srgb(color.xyz), surface_alpha(base_color.a, n))"),
        _before("\nvec3 compute_brdf(", "surface_globals.glsl"),
        ("\n        vec3 spec_contrib = F * G * D / (4.0 * nl * nv + 0.001);\n\n"
         "        vec3 color = nl * radiance * (diffuse_contrib + spec_contrib);\n", glsl("surface_brdf.glsl")),
        ("vec3 dialectric_spec = vec3(min_roughness);",
         "vec3 dialectric_spec = vec3(0.08 * material.emissive_factor.x);"),
        ("    color.xyz += emissive * material.emissive_factor;\n", ""),
        # Quirk 8: the painting reflected and refracted by occluders, in their program variants only.
        _before(_MAIN, "painting_mirror.glsl"),
        _before("\n    frag_color = clamp(vec4(", "painting_mirror_main.glsl", "shadow_fraction_main.glsl"),
        # Quirk 10: the shadow-free colour as a second output.
        ("\nout vec4 frag_color;\n", "\n" + glsl("shadow_free_declaration.glsl")),
        _after("frag_color = clamp(vec4(linear_to_srgb(color.xyz), surface_alpha(base_color.a, n)), 0.0, 1.0);\n",
               glsl("shadow_free_output.glsl")),
    ],
    # The unlit draws (label, opacity) output the Fresnel opacity of the lit draw, highlights aside.
    "flat.frag": [
        _before(_MAIN, "fresnel_opacity.glsl"),
        ("frag_color = clamp(base_color, 0.0, 1.0);",
         "frag_color = vec4(clamp(base_color.rgb, 0.0, 1.0), fresnel_opacity(base_color.a, "
         "clamp(abs(dot(normalize(frag_normal), normalize(cam_pos - frag_position))), 0.0, 1.0)));"),
    ],
}
"""Per pyrender shader file, ``(old, new)`` text replacements, applied after pyrender has resolved
the ``#ifdef`` lines (so no pattern may contain one)."""


def patch_source(filename: str, text: str, defines: dict[str, int]) -> str:
    """pyrender's shader ``filename`` (its text after pyrender's own ``#ifdef`` resolution) with
    :data:`SHADER_PATCHES` applied, ``SIDAR_*`` defines substituted and :data:`PATCH_DEFINES`
    declared for GLSL.

    Raises:
        RuntimeError: a patch's text is not found exactly once (a pyrender release changed it).
    """
    for old, new in SHADER_PATCHES.get(filename, []):
        if text.count(old) != 1:
            raise RuntimeError(f"pyrender shader {filename!r} changed: cannot patch {old.strip()!r}")
        text = text.replace(old, new)
    for name, value in defines.items():  # pyrender substituted its own before the patches
        if name.startswith("SIDAR_"):
            text = text.replace(name, str(value))
    # pyrender resolved its own #ifdef lines before the patches went in; GLSL resolves ours.
    version, rest = text.split("\n", 1)
    declared = "".join(f"#define {name} {int(defines[name])}\n" for name in PATCH_DEFINES if name in defines)
    return f"{version}\n{declared}{rest}"


def surface_factors(specular: float, coat: float, coat_roughness: float) -> np.ndarray:
    """The ``(3,)`` float32 value of a material's ``emissiveFactor`` that the patched shader reads as
    specular level, clear-coat weight and clear-coat roughness (all in [0, 1]; see quirk 5)."""
    return np.array([specular, coat, coat_roughness], dtype=np.float32)
