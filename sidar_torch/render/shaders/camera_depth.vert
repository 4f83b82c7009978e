#version 330 core
// The camera-depth pass: where the mask draw puts a vertex (the same product as depth.vert),
// and its distance along the camera's viewing axis, interpolated perspective-correctly.
layout(location = 0) in vec3 position;
layout(location = INST_M_LOC) in mat4 inst_m;

uniform mat4 P;
uniform mat4 V;
uniform mat4 M;

out float camera_depth;

void main()
{
    vec4 world = M * inst_m * vec4(position, 1.0);
    mat4 light_matrix = P * V;
    gl_Position = light_matrix * world;
    camera_depth = -(V * world).z;  // OpenGL cameras look along their -z
}
