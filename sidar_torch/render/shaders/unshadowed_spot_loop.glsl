        color.xyz += res;
    }
    for (int i = lookup_end; i < n_spot_lights; i++) {  // lights after the lookup range: no lookup
        vec3 l;
        color.xyz += spot_light(i, n, roughness, metallic, f0, c_diff, base_color.rgb, l);
#ifdef SHADOW_FRACTION
        float irradiance = dot(spot_irradiance(i, n), LUMINANCE);  // no lookup: none of it is blocked
        irradiance_all += irradiance;
        irradiance_lit += irradiance;
#endif
    }
    color.xyz += base_color.xyz * ambient_light;
