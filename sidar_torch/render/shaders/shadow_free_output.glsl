#ifdef SHADOW_FREE
    shadow_free_color = clamp(vec4(linear_to_srgb(shadow_free), surface_alpha(base_color.a, n)), 0.0, 1.0);
#endif
