        color.xyz += res;
    }
    for (int i = lookup_end; i < n_spot_lights; i++) {  // lights after the lookup range: no lookup
        vec3 l;
        color.xyz += spot_light(i, n, roughness, metallic, f0, c_diff, base_color.rgb, l);
    }
    color.xyz += base_color.xyz * ambient_light;