#ifdef SHADOW_FRACTION
        vec3 passed = vec3(1.0 - shadow);  // what of light i passes the occluders, per channel
#ifdef TRANSMITTANCE_SHADOWS
        passed *= spot_transmittance(spot_lights[i].light_matrix, i);
#endif
        vec3 irradiance = spot_irradiance(i, frag_position, n);
        irradiance_all += dot(irradiance, LUMINANCE);
        irradiance_lit += dot(irradiance * passed, LUMINANCE);
#endif
