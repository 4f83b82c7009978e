#include "fresnel_opacity.glsl"

float surface_alpha(float alpha, vec3 n)
{
    // Opacity of a blended surface: Schlick-Fresnel towards grazing views, plus its specular light.
    float nv = clamp(abs(dot(n, normalize(cam_pos - frag_position))), 0.0, 1.0);
    return clamp(fresnel_opacity(alpha, nv) + max(specular_light.r, max(specular_light.g, specular_light.b)),
                 0.0, 1.0);
}

uniform float highlight_spill;  // 1: over-exposure spills into the other channels; 0: none

vec3 linear_to_srgb(vec3 c)
{
    // Over-exposure spills into white (highlight_spill 1), or each channel clips on its own (0, as
    // Blender's Standard view transform does).
    c = clamp(c + highlight_spill * max(max(c.r, max(c.g, c.b)) - 1.0, 0.0), 0.0, 1.0);
    return mix(c * 12.92, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, step(vec3(0.0031308), c));
}
