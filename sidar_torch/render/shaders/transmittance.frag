#version 330 core
// One transparent caster's transmittance seen from a spot light (see render.transmittance).
uniform vec4 base_color;      // the caster's linear RGBA base colour
uniform vec3 light_position;  // world frame
in vec3 frag_position;        // world frame
in vec3 frag_normal;
out vec4 frag_color;
#include "fresnel_opacity.glsl"

void main()
{
    float nl = clamp(abs(dot(normalize(frag_normal), normalize(light_position - frag_position))), 0.0, 1.0);
    vec3 tint = base_color.rgb / max(max(base_color.r, max(base_color.g, base_color.b)), 1e-6);
    frag_color = vec4((1.0 - fresnel_opacity(base_color.a, nl)) * tint, 1.0 / gl_FragCoord.w);
}
