        // Light group g without a shadow lookup: all of its emitters' light reaches the fragment, the
        // group's shade times its emitters (as a lookup loop adds it where every lookup returns "lit").
#include "group_shade.glsl"
        color.xyz += shade * emitters;
#ifdef SHADOW_FREE
        shadow_free += shade * emitters;
#endif
#ifdef SHADOW_FRACTION
        float irradiance = dot(spot_irradiance(g, frag_position, n), LUMINANCE) * emitters;  // none of it is blocked
        irradiance_all += irradiance;
        irradiance_lit += irradiance;
#endif
