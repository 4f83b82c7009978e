#ifdef SHADOW_FRACTION
    // The shadow-mask draw: the fraction of the direct light (luminance) the occluders block here.
    // Any blocked light gives at least the first 8-bit level, so a 0 in the mask means none is.
    float blocked = irradiance_all > 0.0 ? clamp(1.0 - irradiance_lit / irradiance_all, 0.0, 1.0) : 0.0;
    frag_color = vec4(vec3(blocked > 0.0 ? max(blocked, 1.0 / 255.0) : 0.0), 1.0);
    return;
#endif
