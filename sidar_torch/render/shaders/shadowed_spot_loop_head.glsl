#ifdef SHADOW_FRACTION
    float irradiance_all = 0.0;  // shadow fraction: every light's direct irradiance (luminance) ...
    float irradiance_lit = 0.0;  // ... and what reaches the fragment past the occluders
#endif
#ifdef SHADOW_FREE
    vec3 shadow_free = color.xyz;  // quirk 10: the colour with every light unblocked
#endif
    // Quirk 13: spot lights g .. g + group_size - 1 are shaded once (spot_light(g), from the group's
    // centre), and the group adds that shade times the sum of its emitters' lookups (each 1 if lit).
    // A program with lookups runs three loops; one without runs one (#else, after pyrender's text).
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
