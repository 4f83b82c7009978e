        // Spot light i without a shadow lookup: all of its light reaches the fragment.
        vec3 l;
        color.xyz += spot_light(i, n, roughness, metallic, f0, c_diff, base_color.rgb, l);
#ifdef SHADOW_FRACTION
        float irradiance = dot(spot_irradiance(i, frag_position, n), LUMINANCE);  // no lookup: none of it is blocked
        irradiance_all += irradiance;
        irradiance_lit += irradiance;
#endif
