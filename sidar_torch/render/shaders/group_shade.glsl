        // Light group g's shade, once; the unshadowed specular light it adds counts once per emitter.
        vec3 specular_before = specular_light;
        vec3 l;
        vec3 shade = spot_light(g, n, roughness, metallic, f0, c_diff, base_color.rgb, l);
        vec3 specular_share = specular_light - specular_before;
        for (int i = g + 1; i < g + spot_lights[g].group_size; i++) {
            specular_light += specular_share;
        }
