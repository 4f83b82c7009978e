
uniform int lookup_begin;  // spot lights lookup_begin .. lookup_end - 1 look their shadows up
uniform int lookup_end;
uniform sampler2DArrayShadow spot_shadow_maps;  // spot light i's map: layer spot_lights[i].shadow_layer

#if SIDAR_SHADOW_TAPS == 0
// Quirk 12: soft shadows (percentage-closer soft shadows) from emitters of radius light_radius.
uniform sampler2DArray spot_shadow_depths;  // the same maps read as depths (a sampler without comparison)
uniform float light_radius;                 // every emitter's radius, world units

const int SOFT_TAPS = 8;
const vec2 SOFT_DISC[SOFT_TAPS] = vec2[](  // Vogel's disc: radius sqrt((k + 1/2) / 8), golden-angle turns
    vec2(0.250, 0.000), vec2(-0.319, 0.292), vec2(0.049, -0.557), vec2(0.402, 0.525),
    vec2(-0.739, -0.131), vec2(0.700, -0.445), vec2(-0.234, 0.870), vec2(-0.446, -0.859));

float soft_shadow(int i, vec3 light_coords, float compare, float w, int layer)
{
    // The share of light i's disc that casters hide from a point at depth w (along the light's axis):
    // the casters' mean depth w_b among the map's texels within soft_reach (the widest penumbra any
    // caster of the view can throw; none there: exactly lit), then a percentage-closer filter over
    // the penumbra light_radius (w - w_b) / (w_b w), in tangent units of the light's frame.
    vec4 depth = spot_lights[i].soft_depth;  // P[2][2], P[2][3], uv per tangent along x and y
    vec2 reach = spot_lights[i].soft_reach * depth.zw;
    float blockers = 0.0, count = 0.0;
    for (int k = 0; k < SOFT_TAPS; k++) {
        float d = texture(spot_shadow_depths, vec3(light_coords.xy + SOFT_DISC[k] * reach, float(layer))).r;
        if (d < compare) {
            blockers += depth.y / (2.0 * d - 1.0 + depth.x);  // window depth back to depth along the axis
            count += 1.0;
        }
    }
    if (count == 0.0) {
        return 0.0;
    }
    float w_b = blockers / count;
    vec2 texel = 0.5 / vec2(textureSize(spot_shadow_maps, 0).xy);
    vec2 radius = max(light_radius * max(w - w_b, 0.0) / (w_b * w) * depth.zw, texel);
    radius = min(radius, reach);
    float lit = 0.0;
    for (int k = 0; k < SOFT_TAPS; k++) {
        lit += texture(spot_shadow_maps, vec4(light_coords.xy + SOFT_DISC[k] * radius, float(layer), compare));
    }
    return 1.0 - lit / float(SOFT_TAPS);
}
#endif

float spot_shadow(int i, mat4 light_matrix, int layer, float nl)
{
    vec4 proj_coords = light_matrix * vec4(frag_position.xyz, 1.0);
    vec3 light_coords = proj_coords.xyz / proj_coords.w * 0.5 + 0.5;
    if (light_coords.z > 1.0) {
        return 0.0;
    }
    float compare = light_coords.z - max(0.001 * (1.0 - nl), 0.0001) / proj_coords.w;
#if SIDAR_SHADOW_TAPS == 0
    return soft_shadow(i, light_coords, compare, proj_coords.w, layer);
#elif SIDAR_SHADOW_TAPS == 1
    float lit = 4.0 * texture(spot_shadow_maps, vec4(light_coords.xy, float(layer), compare));
#else
    vec2 texel = 0.5 / vec2(textureSize(spot_shadow_maps, 0).xy);
    float lit = texture(spot_shadow_maps, vec4(light_coords.xy + vec2(-texel.x, -texel.y), float(layer), compare))
              + texture(spot_shadow_maps, vec4(light_coords.xy + vec2(texel.x, -texel.y), float(layer), compare))
              + texture(spot_shadow_maps, vec4(light_coords.xy + vec2(-texel.x, texel.y), float(layer), compare))
              + texture(spot_shadow_maps, vec4(light_coords.xy + vec2(texel.x, texel.y), float(layer), compare));
#endif
#if SIDAR_SHADOW_TAPS != 0
    return 1.0 - 0.25 * lit;
#endif
}

#ifdef TRANSMITTANCE_SHADOWS
uniform sampler2D transmittance_maps;  // spot light k's tile: transmittance (rgb), nearest caster w (a)
uniform ivec2 transmittance_layout;    // (tile side in texels, tiles per column)

vec3 spot_transmittance(mat4 light_matrix, int k)
{
    // Bilinear filter of light k's transmittance over the 4 nearest texels, each counted only where
    // this fragment lies beyond that texel's nearest transparent caster (0.2 % margin: float16).
    vec4 proj_coords = light_matrix * vec4(frag_position.xyz, 1.0);
    int tile = transmittance_layout.x;
    ivec2 origin = tile * ivec2(k / transmittance_layout.y, k % transmittance_layout.y);
    vec2 st = (proj_coords.xy / proj_coords.w * 0.5 + 0.5) * float(tile) - 0.5;
    ivec2 corner = ivec2(floor(st));
    vec2 f = st - floor(st);
    float depth = proj_coords.w * 0.998;
    vec3 absorbed = vec3(0.0);
    for (int j = 0; j < 4; j++) {
        ivec2 offset = ivec2(j & 1, j >> 1);
        vec4 texel = texelFetch(transmittance_maps, origin + clamp(corner + offset, ivec2(0), ivec2(tile - 1)), 0);
        vec2 weight = mix(1.0 - f, f, vec2(offset));
        absorbed += (depth > texel.a ? weight.x * weight.y : 0.0) * (1.0 - texel.rgb);
    }
    return 1.0 - absorbed;  // exactly 1 where no caster lies between the light and the fragment
}
#endif
