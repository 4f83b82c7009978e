#if defined(PAINTING_REFLECTION) || defined(PAINTING_REFRACTION)
    vec3 mirror_v = normalize(cam_pos - frag_position);
#ifdef PAINTING_REFRACTION
    // Quirk 5's blend, done here with the displaced painting behind: opaque to GL's blending.
    color.xyz = mix(painting_refraction(n, mirror_v, roughness), color.xyz, surface_alpha(base_color.a, n));
    base_color.a = 1.0;
#endif
    color.xyz += painting_reflection(n, mirror_v, roughness, f0);
#endif
