        color.xyz += res;
    }
    for (int i = lookup_end; i < n_spot_lights; i++) {  // lights after the lookup range: no lookup
#include "light_without_lookup.glsl"
    }
    color.xyz += base_color.xyz * ambient_light;
#ifdef SHADOW_FREE
    shadow_free += base_color.xyz * ambient_light;
#endif
