        color.xyz += res;
    }
    for (int i = n_shadowed_spot_lights; i < n_spot_lights; i++) {  // the others: no lookup
        vec3 l;
        color.xyz += spot_light(i, n, roughness, metallic, f0, c_diff, base_color.rgb, l);
    }
    color.xyz += base_color.xyz * ambient_light;