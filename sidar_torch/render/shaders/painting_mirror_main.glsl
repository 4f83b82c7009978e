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
