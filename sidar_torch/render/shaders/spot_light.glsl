float cone_ramp(int i, float cd, float sd)
{
    // Quirk 11: the square root of light i's cone falloff at cos cd and sin sd of the angle from its axis, by
    // its profile (smooth_falloff). pyrender's falloff (0) is the square of a linear ramp r in cos from the
    // outer cone (0) to the inner one (1); Blender's spot blend (1) is smoothstep of that ramp, r^2 (3 - 2 r)
    // (exactly pyrender's ramp at 0: mix gives 1.0); Cycles' area-light spread (2), a Lambertian soft box, is
    // cd (1 - tan / tan a), a the outer cone (cos a = -offset / scale: the inner cone is 0), 1 on the axis.
    // The tangent is sd / cd, sd the length of a cross product: sqrt(1 - cd^2) would turn the last bit of cd
    // near the axis into a step of the light (a frame drawn upside down would round differently there).
    if (spot_lights[i].smooth_falloff > 1.5) {
        float cos_a = -spot_lights[i].light_angle_offset / spot_lights[i].light_angle_scale;
        float tan_ratio = sd * cos_a / (max(cd, 1e-6) * sqrt(max(1.0 - cos_a * cos_a, 1e-12)));  // tan / tan a
        return cd > cos_a ? sqrt(cd * max(1.0 - tan_ratio, 0.0)) : 0.0;
    }
    float r = clamp(cd * spot_lights[i].light_angle_scale + spot_lights[i].light_angle_offset, 0.0, 1.0);
    return r * mix(1.0, sqrt(3.0 - 2.0 * r), spot_lights[i].smooth_falloff);
}

vec3 spot_light(int i, vec3 n, float roughness, float metallic, vec3 f0, vec3 c_diff, vec3 albedo,
                out vec3 l)
{
    // pyrender's spot-light loop body, without the shadow: light i's reflected radiance, from its
    // group's centre (quirk 13; a light's own position and direction in a group of one).
    vec3 position = spot_lights[i].group_position;
    vec3 v = normalize(cam_pos - frag_position); // Vector towards camera
    l = normalize(position - frag_position); // Vector towards light
    vec3 direction = spot_lights[i].group_direction;
    float dist = length(position - frag_position);
    float cd = clamp(dot(direction, -l), 0.0, 1.0);
    float attenuation = cone_ramp(i, cd, length(cross(direction, l)));
    attenuation = attenuation * attenuation * spot_lights[i].intensity;
    attenuation = attenuation / (dist * dist);
    vec3 radiance = attenuation * spot_lights[i].color;
    return compute_brdf(n, v, l, roughness, metallic, f0, c_diff, albedo, radiance);
}

vec3 spot_irradiance(int i, vec3 p, vec3 n)
{
    // Spot light i's direct irradiance at point p of normal n, per channel: cone and distance
    // falloff as in spot_light, times n . l (the painting's light in a mirror, the weight of a
    // light's shadow in the shadow fraction).
    vec3 to_light = spot_lights[i].group_position - p;
    float dist = length(to_light);
    vec3 l = to_light / dist;
    float cd = clamp(dot(spot_lights[i].group_direction, -l), 0.0, 1.0);
    float spot = cone_ramp(i, cd, length(cross(spot_lights[i].group_direction, l)));
    return max(dot(n, l), 0.0) * spot * spot * spot_lights[i].intensity / (dist * dist) * spot_lights[i].color;
}

#ifdef SHADOW_FRACTION
const vec3 LUMINANCE = vec3(0.2126, 0.7152, 0.0722);  // linear sRGB (Rec. 709) primaries
#endif
