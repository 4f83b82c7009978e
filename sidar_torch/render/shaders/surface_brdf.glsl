
        vec3 spec_contrib = F * G * D / (4.0 * nl * nv + 0.001);

        // Clear coat: a GGX lobe of 4 % reflectance and roughness material.emissive_factor.z.
        float coat = material.emissive_factor.y;
        PBRInfo coat_info = PBRInfo(nl, nv, nh, lh, vh, max(material.emissive_factor.z, min_roughness),
                                    0.0, vec3(0.04), vec3(0.0));
        float coat_f = specular_reflection(coat_info).x * coat;
        float coat_spec = coat_f * geometric_occlusion(coat_info) * microfacet_distribution(coat_info)
                        / (4.0 * nl * nv + 0.001);
        specular_light += nl * radiance * (spec_contrib + coat_spec);

        vec3 color = nl * radiance * ((diffuse_contrib + spec_contrib) * (1.0 - coat_f) + coat_spec);
