        // Light group g without a shadow lookup: all of its emitters' light reaches the fragment.
#include "group_shade.glsl"
#ifdef SHADOW_FRACTION
        float irradiance = dot(spot_irradiance(g, frag_position, n), LUMINANCE);  // no lookup: none of it is blocked
#endif
        for (int i = g; i < g + spot_lights[g].group_size; i++) {
            color.xyz += shade;
#ifdef SHADOW_FREE
            shadow_free += shade;
#endif
#ifdef SHADOW_FRACTION
            irradiance_all += irradiance;
            irradiance_lit += irradiance;
#endif
        }
