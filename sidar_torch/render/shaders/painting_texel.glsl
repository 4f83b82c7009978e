#ifdef HAS_BASE_COLOR_TEX
vec4 painting_texel(sampler2D image, vec2 uv)
{
    // The painting at uv as this pixel sees it (quirk 15): one trilinear lookup, or with SIDAR_TEXTURE_TAPS N
    // the mean of N x N lookups on a grid over the pixel's footprint, each with N-times smaller derivatives.
    // Along each screen axis the grid spans clamp(f - 1, 0, 1) of the pixel, f the texels the pixel spans
    // along it: no spread where the view does not shrink the painting (there every lookup is the bilinear
    // one of level 0, as a single lookup's), the whole pixel from 2 texels per pixel on.
#ifdef SIDAR_TEXTURE_TAPS
    vec2 texels = vec2(textureSize(image, 0));
    vec2 du = dFdx(uv);
    vec2 dv = dFdy(uv);
    float n = float(SIDAR_TEXTURE_TAPS);
    vec2 su = du * clamp(length(du * texels) - 1.0, 0.0, 1.0);  // the grid's extent along the pixel's x ...
    vec2 sv = dv * clamp(length(dv * texels) - 1.0, 0.0, 1.0);  // ... and y, in texture coordinates
    vec4 sum = vec4(0.0);
    for (int i = 0; i < SIDAR_TEXTURE_TAPS; i++) {
        for (int j = 0; j < SIDAR_TEXTURE_TAPS; j++) {
            vec2 at = (vec2(float(i), float(j)) + 0.5) / n - 0.5;  // in [-0.5, 0.5]: where in the grid
            sum += textureGrad(image, uv + at.x * su + at.y * sv, du / n, dv / n);
        }
    }
    return sum / (n * n);
#else
    return texture(image, uv);
#endif
}
#endif
