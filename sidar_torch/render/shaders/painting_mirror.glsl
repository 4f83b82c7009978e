
#if defined(PAINTING_REFLECTION) || defined(PAINTING_REFRACTION)
// Quirk 8: the painting seen in a reflective occluder (PAINTING_REFLECTION) or through a glass one
// (PAINTING_REFRACTION: reflection and refraction), first bounce only (see render.mirror).
uniform sampler2D painting;       // the painting's texture (sRGB, mipmapped, trilinear sampler)
uniform vec2 painting_half_size;  // half width and height of the painting (world, in z = 0, centred)
uniform float painting_diffuse;   // the painting material's diffuse factor (mirror.painting_diffuse)
uniform float material_ior;       // the occluder's index of refraction (PAINTING_REFRACTION)
uniform mat4 object_from_world;   // the occluder's inverse pose: its unit primitive's frame

struct PaintingHit {
    vec2 uv;       // texture coordinates where the ray meets z = 0
    float seen;    // 1 if it meets the painting going down, else 0 (the black world)
    float lod;     // mip level of one pixel's footprint there
    float scale;   // texels per radian of spread at the hit (see painting_radiance)
    vec3 light;    // what multiplies the albedo there: ambient plus the spot lights, unshadowed
};

PaintingHit painting_hit(vec3 origin, vec3 dir)
{
    // Where origin + s dir (s > 0) meets the painting, and the light falling there. Computed in
    // uniform control flow (the pixel footprint comes from screen-space derivatives).
    PaintingHit hit;
    float down = min(dir.z, -1e-6);
    float s = -origin.z / down;
    vec3 p = origin + s * dir;
    vec2 size = vec2(textureSize(painting, 0));
    hit.uv = p.xy / (2.0 * painting_half_size) + 0.5;
    hit.seen = float(dir.z < -1e-6 && origin.z > 0.0 && all(lessThanEqual(abs(p.xy), painting_half_size)));
    vec2 dx = dFdx(hit.uv) * size, dy = dFdy(hit.uv) * size;
    hit.lod = 0.5 * log2(max(max(dot(dx, dx), dot(dy, dy)), 1e-12));
    // A cone of half-angle a around dir covers a disc of radius s a / sqrt(|dir.z|) on the plane
    // (geometric mean of the ellipse's axes s a and s a / |dir.z|); diameter in texels per a:
    hit.scale = 2.0 * s / sqrt(-down) * size.y / (2.0 * painting_half_size.y);
    vec3 irradiance = vec3(0.0);
    for (int i = 0; i < n_spot_lights; i++) {
        irradiance += spot_irradiance(i, p, vec3(0.0, 0.0, 1.0));  // the painting faces +z
    }
    hit.light = ambient_light + painting_diffuse / PI * irradiance;
    return hit;
}

vec3 painting_radiance(PaintingHit hit, float spread)
{
    // The painting's radiance along the ray, blurred over a cone of half-angle spread (radians).
    float blur = spread * hit.scale;
    float lod = 0.5 * log2(exp2(2.0 * hit.lod) + blur * blur);
    return hit.seen * srgb_to_linear(textureLod(painting, hit.uv, lod)).rgb * hit.light;
}

vec3 painting_reflection(vec3 n, vec3 v, float roughness, vec3 f0)
{
    // The painting reflected by the base layer (Schlick-Fresnel with f0, GGX lobe of half-width
    // roughness^2 as a blur) and by the clear coat (4 %, its own roughness) over it.
    float nv = clamp(dot(n, v), 0.0, 1.0);
    float schlick = pow(1.0 - nv, 5.0);
    float coat = material.emissive_factor.y * (0.04 + 0.96 * schlick);
    float coat_roughness = max(material.emissive_factor.z, min_roughness);
    PaintingHit hit = painting_hit(frag_position, reflect(-v, n));
    vec3 base = (f0 + (1.0 - f0) * schlick) * (1.0 - coat) * painting_radiance(hit, roughness * roughness);
    return base + coat * painting_radiance(hit, coat_roughness * coat_roughness);
}

#ifdef PAINTING_REFRACTION
vec3 painting_refraction(vec3 n, vec3 v, float roughness)
{
    // The painting through the glass: refracted at this (entry) point, then at the exit from the
    // occluder's unit sphere in its own frame (exact for a sphere or ellipsoid; other shapes exit
    // through that ellipsoid, or, where the ray misses it, parallel to the entry face: a thin plate).
    // Total internal reflection at the exit is black.
    vec3 inside = refract(-v, n, 1.0 / material_ior);
    vec3 o = (object_from_world * vec4(frag_position, 1.0)).xyz;
    vec3 d = mat3(object_from_world) * inside;
    float b = dot(o, d), a = dot(d, d), disc = b * b - a * (dot(o, o) - 1.0);
    float t = disc > 0.0 ? max((-b + sqrt(disc)) / a, 0.0) : 0.0;
    vec3 exit_normal = disc > 0.0 ? normalize(transpose(mat3(object_from_world)) * (o + t * d)) : n;
    vec3 out_dir = refract(inside, -exit_normal, material_ior);
    return painting_radiance(painting_hit(frag_position + t * inside, out_dir), roughness * roughness);
}
#endif
#endif
