#ifdef SHADOW_FREE
layout(location = 0) out vec4 frag_color;
layout(location = 1) out vec4 shadow_free_color;  // quirk 10: the second colour attachment
#else
out vec4 frag_color;
#endif
