#version 330 core
// The unlit surface (label, opacity draws): base colour and the lit draw's Fresnel opacity (quirk 5).
// Derived from pyrender's shaders/flat.frag (MIT License, Copyright (c) 2019 Matthew Matl).

struct Material {
    vec3 emissive_factor;
    vec4 base_color_factor;
    float metallic_factor;
    float roughness_factor;
#ifdef HAS_BASE_COLOR_TEX
    sampler2D base_color_texture;
#endif
};

uniform Material material;
uniform vec3 cam_pos;

in vec3 frag_position;
#ifdef NORMAL_LOC
in vec3 frag_normal;
#endif
#ifdef TEXCOORD_0_LOC
in vec2 uv_0;
#endif

out vec4 frag_color;

#include "fresnel_opacity.glsl"

void main()
{
    vec4 base_color = material.base_color_factor;
#ifdef HAS_BASE_COLOR_TEX
    base_color = base_color * texture(material.base_color_texture, uv_0);
#endif
    frag_color = vec4(clamp(base_color.rgb, 0.0, 1.0), fresnel_opacity(base_color.a, clamp(abs(dot(normalize(frag_normal), normalize(cam_pos - frag_position))), 0.0, 1.0)));
}
