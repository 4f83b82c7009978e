        // Spot light i without a shadow lookup: all of its light reaches the fragment.
        vec3 l;
        vec3 res = spot_light(i, n, roughness, metallic, f0, c_diff, base_color.rgb, l);
        color.xyz += res;
#ifdef SHADOW_FREE
        shadow_free += res;
#endif
#ifdef SHADOW_FRACTION
        float irradiance = dot(spot_irradiance(i, frag_position, n), LUMINANCE);  // no lookup: none of it is blocked
        irradiance_all += irradiance;
        irradiance_lit += irradiance;
#endif
