        visibility += res;
    }
        color.xyz += shade * visibility;
    }
    for (int g = lookup_end; g < n_spot_lights; g += spot_lights[g].group_size) {  // lights after the lookup range: no lookup
#include "light_without_lookup.glsl"
    }
#elif defined(LIGHT_GROUPS)
    // No lookup, and LIGHT_GROUPS light groups (up to 4; the painting's program, see
    // pyrender_overrides.ProgramCache): written out, no loop left, the same additions in the same order.
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
