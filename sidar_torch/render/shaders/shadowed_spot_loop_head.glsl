    for (int i = 0; i < n_shadowed_spot_lights; i++) {  // lights with a shadow lookup
        vec3 l;
        vec3 res = spot_light(i, n, roughness, metallic, f0, c_diff, base_color.rgb, l);
