#version 330 core
// The lit surface (painting and occluders): spot lights in three loops, shadow lookups, mirrors; quirks in render/programs.py.
// Derived from pyrender's shaders/mesh.frag (MIT License, Copyright (c) 2019 Matthew Matl).
///////////////////////////////////////////////////////////////////////////////
// Structs
///////////////////////////////////////////////////////////////////////////////

struct SpotLight {
    vec3 color;
    float intensity;
    float range;
    vec3 position;
    vec3 direction;
    float light_angle_scale;
    float light_angle_offset;
    float smooth_falloff;
    vec4 soft_depth;
    float soft_reach;
    vec3 group_position;
    vec3 group_direction;
    int group_size;

    #ifdef SPOT_LIGHT_SHADOWS
    int shadow_layer;
    mat4 light_matrix;
    #endif
};

struct Material {
    vec3 emissive_factor;  // quirk 5: (specular level, clear-coat weight, clear-coat roughness)
    vec4 base_color_factor;
    float metallic_factor;
    float roughness_factor;
#ifdef HAS_BASE_COLOR_TEX
    sampler2D base_color_texture;
#endif
};

struct PBRInfo {
    float nl;
    float nv;
    float nh;
    float lh;
    float vh;
    float roughness;
    float metallic;
    vec3 f0;
    vec3 c_diff;
};

///////////////////////////////////////////////////////////////////////////////
// Uniforms
///////////////////////////////////////////////////////////////////////////////
uniform Material material;
layout(std140) uniform SpotLights {
    SpotLight spot_lights[MAX_SPOT_LIGHTS];
};
uniform int n_spot_lights;
uniform vec3 cam_pos;
uniform vec3 ambient_light;

///////////////////////////////////////////////////////////////////////////////
// Inputs
///////////////////////////////////////////////////////////////////////////////

in vec3 frag_position;
#ifdef NORMAL_LOC
in vec3 frag_normal;
#endif
#ifdef TEXCOORD_0_LOC
in vec2 uv_0;
#endif

///////////////////////////////////////////////////////////////////////////////
// OUTPUTS
///////////////////////////////////////////////////////////////////////////////

#ifdef SHADOW_FREE
layout(location = 0) out vec4 frag_color;
layout(location = 1) out vec4 shadow_free_color;  // quirk 10: the second colour attachment
#else
out vec4 frag_color;
#endif

///////////////////////////////////////////////////////////////////////////////
// Constants
///////////////////////////////////////////////////////////////////////////////
const float PI = 3.141592653589793;
const float min_roughness = 0.04;

///////////////////////////////////////////////////////////////////////////////
// Utility Functions
///////////////////////////////////////////////////////////////////////////////
vec4 srgb_to_linear(vec4 srgb)
{
    vec3 b_less = step(vec3(0.04045),srgb.xyz);
    vec3 lin_out = mix( srgb.xyz/vec3(12.92), pow((srgb.xyz+vec3(0.055))/vec3(1.055),vec3(2.4)), b_less );
    return vec4(lin_out, srgb.w);
}

// Normal computation
vec3 get_normal()
{
#ifdef NORMAL_LOC
    return frag_normal;
#else
    return normalize(cam_pos - frag_position);
#endif
}

// Fresnel
vec3 specular_reflection(PBRInfo info)
{
     vec3 res = info.f0 + (1.0 - info.f0) * pow(clamp(1.0 - info.vh, 0.0, 1.0), 5.0);
     return res;
}

// Smith
float geometric_occlusion(PBRInfo info)
{
    float r = info.roughness + 1.0;
    float k = r * r  / 8.0;
    float g1 = info.nv / (info.nv * (1.0 - k) + k);
    float g2 = info.nl / (info.nl * (1.0 - k) + k);
    return g1 * g2;
}

float microfacet_distribution(PBRInfo info)
{
    float a = info.roughness * info.roughness;
    float a2 = a * a;
    float nh2 = info.nh * info.nh;

    float denom = (nh2 * (a2 - 1.0) + 1.0);
    return a2 / (PI * denom * denom);
}

vec3 specular_light = vec3(0.0);  // specular light reflected towards the camera, unshadowed

vec3 compute_brdf(vec3 n, vec3 v, vec3 l,
                  float roughness, float metalness,
                  vec3 f0, vec3 c_diff, vec3 albedo,
                  vec3 radiance)
{
        vec3 h = normalize(l+v);
        float nl = clamp(dot(n, l), 0.001, 1.0);
        float nv = clamp(abs(dot(n, v)), 0.001, 1.0);
        float nh = clamp(dot(n, h), 0.0, 1.0);
        float lh = clamp(dot(l, h), 0.0, 1.0);
        float vh = clamp(dot(v, h), 0.0, 1.0);

        PBRInfo info = PBRInfo(nl, nv, nh, lh, vh, roughness, metalness, f0, c_diff);

        // Compute PBR terms
        vec3 F = specular_reflection(info);
        float G = geometric_occlusion(info);
        float D = microfacet_distribution(info);

        // Compute BRDF
        vec3 diffuse_contrib = (1.0 - F) * c_diff / PI;
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
        return color;
}

///////////////////////////////////////////////////////////////////////////////
// MAIN
///////////////////////////////////////////////////////////////////////////////
#include "painting_texel.glsl"
#include "spot_shadow.glsl"
#include "spot_light.glsl"
#include "surface_output.glsl"
#include "painting_mirror.glsl"

void main()
{
    vec4 color = vec4(vec3(0.0), 1.0);

    // Compute metallic/roughness factors
    float roughness = material.roughness_factor;
    float metallic = material.metallic_factor;
    roughness = clamp(roughness, min_roughness, 1.0);
    metallic = clamp(metallic, 0.0, 1.0);

    // Compute albedo
    vec4 base_color = material.base_color_factor;
#ifdef HAS_BASE_COLOR_TEX
    base_color = base_color * srgb_to_linear(painting_texel(material.base_color_texture, uv_0));
#endif

    // Compute specular and diffuse colors
    vec3 dialectric_spec = vec3(0.08 * material.emissive_factor.x);
    vec3 c_diff = mix(vec3(0.0), base_color.rgb * (1 - min_roughness), 1.0 - metallic);
    vec3 f0 = mix(dialectric_spec, base_color.rgb, metallic);

    // Compute normal
    vec3 n = normalize(get_normal());

#ifdef SHADOW_FRACTION
    float irradiance_all = 0.0;  // shadow fraction: every light's direct irradiance (luminance) ...
    float irradiance_lit = 0.0;  // ... and what reaches the fragment past the occluders
#endif
#ifdef SHADOW_FREE
    vec3 shadow_free = color.xyz;  // quirk 10: the colour with every light unblocked
#endif
    // Quirk 13: spot lights g .. g + group_size - 1 are shaded once (spot_light(g), from the group's
    // centre), and the group adds that shade times the sum of its emitters' lookups (each 1 if lit).
    // A program with lookups runs three loops; one without runs one (#else below).
#ifdef SPOT_LIGHT_SHADOWS
    for (int g = 0; g < lookup_begin; g += spot_lights[g].group_size) {  // lights before the lookup range: no lookup
#include "light_without_lookup.glsl"
    }
    for (int g = lookup_begin; g < lookup_end; g += spot_lights[g].group_size) {  // lights with a shadow lookup
#include "group_shade.glsl"
#ifdef SHADOW_FREE
        shadow_free += shade * emitters;  // before the lookups darken it
#endif
        vec3 visibility = vec3(0.0);  // the group's emitters' light that passes the occluders, summed
      for (int i = g; i < g + spot_lights[g].group_size; i++) {  // each emitter's lookup
        vec3 res = vec3(1.0);  // what of emitter i's light passes the occluders (1: all)
        l = normalize(spot_lights[i].position - frag_position);  // this emitter's: its lookup's slope bias
#ifdef SPOT_LIGHT_SHADOWS
        float nl = clamp(dot(n,l), 0.0, 1.0);
        float shadow = spot_shadow(i,
            spot_lights[i].light_matrix,
            spot_lights[i].shadow_layer,
            nl
        );
        res = res * (1.0 - shadow);
#ifdef TRANSMITTANCE_SHADOWS
        res *= spot_transmittance(spot_lights[i].light_matrix, i);  // in the shadowed loop only
#endif
#ifdef SHADOW_FRACTION
        vec3 passed = vec3(1.0 - shadow);  // what of light i passes the occluders, per channel
#ifdef TRANSMITTANCE_SHADOWS
        passed *= spot_transmittance(spot_lights[i].light_matrix, i);
#endif
        vec3 irradiance = spot_irradiance(i, frag_position, n);
        irradiance_all += dot(irradiance, LUMINANCE);
        irradiance_lit += dot(irradiance * passed, LUMINANCE);
#endif
#endif
        visibility += res;
    }
        color.xyz += shade * visibility;
    }
    for (int g = lookup_end; g < n_spot_lights; g += spot_lights[g].group_size) {  // lights after the lookup range: no lookup
#include "light_without_lookup.glsl"
    }
#elif defined(LIGHT_GROUPS)
    // No lookup, and LIGHT_GROUPS light groups (up to 4; the painting's program, see
    // programs.ProgramCache): written out, no loop left, the same additions in the same order.
    int g = 0;
#if LIGHT_GROUPS > 0
    {
#include "light_without_lookup.glsl"
    }
    g += spot_lights[g].group_size;
#endif
#if LIGHT_GROUPS > 1
    {
#include "light_without_lookup.glsl"
    }
    g += spot_lights[g].group_size;
#endif
#if LIGHT_GROUPS > 2
    {
#include "light_without_lookup.glsl"
    }
    g += spot_lights[g].group_size;
#endif
#if LIGHT_GROUPS > 3
    {
#include "light_without_lookup.glsl"
    }
#endif
#else  // no lookup in this program: every light in one loop, the same additions in the same order
    for (int g = 0; g < n_spot_lights; g += spot_lights[g].group_size) {
#include "light_without_lookup.glsl"
    }
#endif
    color.xyz += base_color.xyz * ambient_light;
#ifdef SHADOW_FREE
    shadow_free += base_color.xyz * ambient_light;
#endif

#if defined(PAINTING_REFLECTION) || defined(PAINTING_REFRACTION)
    vec3 mirror_v = normalize(cam_pos - frag_position);
#ifdef PAINTING_REFRACTION
    // Quirk 5's blend, done here with the displaced painting behind: opaque to GL's blending.
    vec3 refracted = base_color.rgb * painting_refraction(n, mirror_v, roughness);  // tinted by the glass
    float glass_alpha = surface_alpha(base_color.a, n);
    color.xyz = mix(refracted, color.xyz, glass_alpha);
#ifdef SHADOW_FREE
    shadow_free = mix(refracted, shadow_free, glass_alpha);
#endif
    base_color.a = 1.0;
#endif
    vec3 reflected = painting_reflection(n, mirror_v, roughness, f0);
    color.xyz += reflected;
#ifdef SHADOW_FREE
    shadow_free += reflected;
#endif
#endif
#ifdef SHADOW_FRACTION
    // The shadow-mask draw: the fraction of the direct light (luminance) the occluders block here.
    // Any blocked light gives at least the first 8-bit level, so a 0 in the mask means none is.
    float blocked = irradiance_all > 0.0 ? clamp(1.0 - irradiance_lit / irradiance_all, 0.0, 1.0) : 0.0;
    frag_color = vec4(vec3(blocked > 0.0 ? max(blocked, 1.0 / 255.0) : 0.0), 1.0);
    return;
#endif

    frag_color = clamp(vec4(linear_to_srgb(color.xyz), surface_alpha(base_color.a, n)), 0.0, 1.0);
#ifdef SHADOW_FREE
    shadow_free_color = clamp(vec4(linear_to_srgb(shadow_free), surface_alpha(base_color.a, n)), 0.0, 1.0);
#endif
}
