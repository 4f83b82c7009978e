        color.xyz += res;
    }
    }
    for (int g = lookup_end; g < n_spot_lights; g += spot_lights[g].group_size) {  // lights after the lookup range: no lookup
#include "light_without_lookup.glsl"
    }
#else  // no lookup in this program: every light in one loop, the same additions in the same order
    for (int g = 0; g < n_spot_lights; g += spot_lights[g].group_size) {
#include "light_without_lookup.glsl"
    }
#endif
    color.xyz += base_color.xyz * ambient_light;
#ifdef SHADOW_FREE
    shadow_free += base_color.xyz * ambient_light;
#endif
