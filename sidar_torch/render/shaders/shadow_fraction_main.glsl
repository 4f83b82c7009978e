#ifdef SHADOW_FRACTION
    // The shadow-mask draw: the fraction of the direct light (luminance) the occluders block here.
    frag_color = vec4(vec3(irradiance_all > 0.0 ? clamp(1.0 - irradiance_lit / irradiance_all, 0.0, 1.0) : 0.0), 1.0);
    return;
#endif
