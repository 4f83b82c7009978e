#version 400 core
// The lens's resampling pass (render.resample): each fragment is a pixel (u, v) of the distorted
// output view (Kornia pixels: u = gl_FragCoord.x - 0.5, v = gl_FragCoord.y - 0.5, drawn upright, so the
// first row in memory is v = 0). Its source is where the pinhole camera sees the same ray, in float32:
//   LENS_DIVISION       x_u = x_d / (1 + lambda |x_d|^2), closed form;
//   LENS_BROWN_CONRADY  the inverse of OpenCV's distortion: NEWTON_STEPS Newton steps from
//                       x_d / (1 + k1 r^2 + k2 r^4 + k3 r^6), r = |x_d|;
// x normalised camera coordinates K^-1 (u, v, 1) (sidar_torch.choices.lenses). The source, in the
// canvas window's pixels (minus origin) and clamped to the window (grid_sample's border padding), is
// blended bilinearly from the four window pixels around it with float weights: one textureGather of
// the R32UI layer, each texel four 8-bit levels (bytes 0..3). Output 0: the four levels rounded half to
// even. In layer 0 byte 3 is the pixel's state (0 painting seen, 1 masked, 2 background: masked and
// nothing drawn); outputs 1 and 2 are the mask and the background, each its fraction cut at 1/2 (0 or
// 1). With SOURCES the fragment writes its source (view pixels) instead.

uniform usampler2DArray canvas;
uniform int layer;
uniform vec2 texture_size; // (W, H) of the array's storage
uniform vec2 window;       // (w, h) pixels of this view's window (its first columns and rows)
uniform vec2 origin;       // the view pixel (x, y) at window pixel (0, 0)
uniform vec4 intrinsics;   // K's (f_x, skew, c_x, f_y)
uniform float c_y;
uniform vec4 lens;         // brown_conrady (k1, k2, p1, p2); division (lambda, 0, 0, 0)
uniform float k3;

#ifdef SOURCES
out vec4 frag_source;
#else
layout(location = 0) out uvec4 frag_levels;
layout(location = 1) out uvec4 frag_masked;
layout(location = 2) out uvec4 frag_background;
#endif

vec2 undistorted(vec2 x)
{
#ifdef LENS_DIVISION
    return x * (1.0 / (1.0 + lens.x * dot(x, x)));
#else
    float k1 = lens.x, k2 = lens.y, p1 = lens.z, p2 = lens.w;
    float d2 = dot(x, x);
    vec2 u = x * (1.0 / (1.0 + d2 * (k1 + d2 * (k2 + d2 * k3))));
    for (int k = 0; k < NEWTON_STEPS; ++k) {
        float uu = u.x * u.x, vv = u.y * u.y, uv = u.x * u.y, r2 = uu + vv;
        float a = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
        vec2 f = vec2(u.x * a + 2.0 * p1 * uv + p2 * (r2 + 2.0 * uu),
                      u.y * a + p1 * (r2 + 2.0 * vv) + 2.0 * p2 * uv) - x;
        float g = 2.0 * k1 + r2 * (4.0 * k2 + 6.0 * k3 * r2);  // d a / d u = g u, d a / d v = g v
        float j11 = a + g * uu + 2.0 * p1 * u.y + 6.0 * p2 * u.x;
        float j12 = g * uv + 2.0 * p1 * u.x + 2.0 * p2 * u.y;
        float j22 = a + g * vv + 6.0 * p1 * u.y + 2.0 * p2 * u.x;
        u -= vec2(j22 * f.x - j12 * f.y, j11 * f.y - j12 * f.x) * (1.0 / (j11 * j22 - j12 * j12));
    }
    return u;
#endif
}

void main()
{
    vec2 pixel = gl_FragCoord.xy - 0.5;
    float y = (pixel.y - c_y) / intrinsics.w;
    vec2 u = undistorted(vec2((pixel.x - intrinsics.z - intrinsics.y * y) / intrinsics.x, y));
    vec2 source = vec2(intrinsics.x * u.x + intrinsics.y * u.y + intrinsics.z, intrinsics.w * u.y + c_y);
#ifdef SOURCES
    frag_source = vec4(source, 0.0, 1.0);
#else
    vec2 p = clamp(source - origin, vec2(0.0), window - 1.0);
    vec2 p0 = floor(p);
    vec2 t = p - p0;
    // The gather's footprint is (p0, p0 + 1) exactly: its coordinate lies half-way between their centres.
    uvec4 q = textureGather(canvas, vec3((p0 + 1.0) / texture_size, float(layer)));
    vec4 w = vec4((1.0 - t.x) * t.y, t.x * t.y, t.x * (1.0 - t.y), (1.0 - t.x) * (1.0 - t.y));  // gather's order
    vec4 fourth = vec4(q >> 24u);
    frag_levels = uvec4(roundEven(vec4(dot(w, vec4(q & 255u)), dot(w, vec4((q >> 8u) & 255u)),
                                       dot(w, vec4((q >> 16u) & 255u)), dot(w, fourth))));
    frag_masked = uvec4(uint(dot(w, step(0.5, fourth)) >= 0.5));
    frag_background = uvec4(uint(dot(w, step(1.5, fourth)) >= 0.5));
#endif
}
