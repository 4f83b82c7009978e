#version 330 core
// The camera-frame pass: where the mask draw puts a vertex (the same product as depth.vert), and what
// the pass writes, interpolated perspective-correctly: with CAMERA_DEPTH the distance along the
// camera's viewing axis, with CAMERA_NORMALS the surface normal in the camera's OpenGL frame.
layout(location = 0) in vec3 position;
#ifdef CAMERA_NORMALS
layout(location = NORMAL_LOC) in vec3 normal;
#endif
layout(location = INST_M_LOC) in mat4 inst_m;

uniform mat4 P;
uniform mat4 V;
uniform mat4 M;

#ifdef CAMERA_DEPTH
out float camera_depth;
#endif
#ifdef CAMERA_NORMALS
out vec3 camera_normal;
#endif

void main()
{
    vec4 world = M * inst_m * vec4(position, 1.0);
    mat4 light_matrix = P * V;
    gl_Position = light_matrix * world;
#ifdef CAMERA_DEPTH
    camera_depth = -(V * world).z;  // OpenGL cameras look along their -z
#endif
#ifdef CAMERA_NORMALS
    // Normals go by the inverse transpose of the model matrix (scaled occluders); V is a rotation.
    camera_normal = mat3(V) * (transpose(inverse(mat3(M * inst_m))) * normal);
#endif
}
