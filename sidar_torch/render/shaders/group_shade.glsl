        // Light group g's shade, once; the unshadowed specular light it adds counts once per emitter
        // (a product, not a loop: quirk 6).
        vec3 specular_before = specular_light;
        vec3 l;
        vec3 shade = spot_light(g, n, roughness, metallic, f0, c_diff, base_color.rgb, l);
        float emitters = float(spot_lights[g].group_size);
        specular_light += (specular_light - specular_before) * (emitters - 1.0);
