#ifdef SHADOW_FRACTION
    float irradiance_all = 0.0;  // shadow fraction: every light's direct irradiance (luminance) ...
    float irradiance_lit = 0.0;  // ... and what reaches the fragment past the occluders
#endif
#ifdef SHADOW_FREE
    vec3 shadow_free = color.xyz;  // quirk 10: the colour with every light unblocked
#endif
    for (int i = 0; i < lookup_begin; i++) {  // lights before the lookup range: no lookup
#include "light_without_lookup.glsl"
    }
    for (int i = lookup_begin; i < lookup_end; i++) {  // lights with a shadow lookup
        vec3 l;
        vec3 res = spot_light(i, n, roughness, metallic, f0, c_diff, base_color.rgb, l);
#ifdef SHADOW_FREE
        shadow_free += res;  // before the lookup darkens it
#endif
