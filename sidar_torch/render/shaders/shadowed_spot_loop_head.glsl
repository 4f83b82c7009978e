    for (int i = 0; i < lookup_begin; i++) {  // lights before the lookup range: no lookup
        vec3 l;
        color.xyz += spot_light(i, n, roughness, metallic, f0, c_diff, base_color.rgb, l);
    }
    for (int i = lookup_begin; i < lookup_end; i++) {  // lights with a shadow lookup
        vec3 l;
        vec3 res = spot_light(i, n, roughness, metallic, f0, c_diff, base_color.rgb, l);
