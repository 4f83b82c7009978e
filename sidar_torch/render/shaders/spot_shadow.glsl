
uniform int lookup_begin;  // spot lights lookup_begin .. lookup_end - 1 look their shadows up
uniform int lookup_end;
uniform sampler2DArrayShadow spot_shadow_maps;  // spot light i's map: layer spot_lights[i].shadow_layer

float spot_shadow(mat4 light_matrix, int layer, float nl)
{
    vec4 proj_coords = light_matrix * vec4(frag_position.xyz, 1.0);
    vec3 light_coords = proj_coords.xyz / proj_coords.w * 0.5 + 0.5;
    if (light_coords.z > 1.0) {
        return 0.0;
    }
    float compare = light_coords.z - max(0.001 * (1.0 - nl), 0.0001) / proj_coords.w;
#if SIDAR_SHADOW_TAPS == 1
    float lit = 4.0 * texture(spot_shadow_maps, vec4(light_coords.xy, float(layer), compare));
#else
    vec2 texel = 0.5 / vec2(textureSize(spot_shadow_maps, 0).xy);
    float lit = texture(spot_shadow_maps, vec4(light_coords.xy + vec2(-texel.x, -texel.y), float(layer), compare))
              + texture(spot_shadow_maps, vec4(light_coords.xy + vec2(texel.x, -texel.y), float(layer), compare))
              + texture(spot_shadow_maps, vec4(light_coords.xy + vec2(-texel.x, texel.y), float(layer), compare))
              + texture(spot_shadow_maps, vec4(light_coords.xy + vec2(texel.x, texel.y), float(layer), compare));
#endif
    return 1.0 - 0.25 * lit;
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
