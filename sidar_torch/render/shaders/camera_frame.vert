#version 330 core
// The camera-frame pass: where the mask draw puts a vertex (the same product as depth.vert), and what
// the pass writes, interpolated perspective-correctly: with CAMERA_DEPTH the distance along the
// camera's viewing axis.
layout(location = 0) in vec3 position;
layout(location = INST_M_LOC) in mat4 inst_m;

uniform mat4 P;
uniform mat4 V;
uniform mat4 M;

#ifdef CAMERA_DEPTH
out float camera_depth;
#endif

void main()
{
    vec4 world = M * inst_m * vec4(position, 1.0);
    mat4 light_matrix = P * V;
    gl_Position = light_matrix * world;
#ifdef CAMERA_DEPTH
    camera_depth = -(V * world).z;  // OpenGL cameras look along their -z
#endif
}
