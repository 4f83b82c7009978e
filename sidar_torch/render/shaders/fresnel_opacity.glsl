
float fresnel_opacity(float alpha, float cos_angle)
{
    // A blended surface's opacity, raised towards 1 by the Schlick-Fresnel reflectance (4 % head-on).
    float fresnel = 0.04 + 0.96 * pow(1.0 - cos_angle, 5.0);
    return mix(alpha, 1.0, fresnel);
}
