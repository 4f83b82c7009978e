#version 330 core
// Position only: the shadow maps' and the mask's vertex stage.
// Derived from pyrender's shaders/mesh_depth.vert (MIT License, Copyright (c) 2019 Matthew Matl).
layout(location = 0) in vec3 position;
layout(location = INST_M_LOC) in mat4 inst_m;

uniform mat4 P;
uniform mat4 V;
uniform mat4 M;

void main()
{
    mat4 light_matrix = P * V;
    gl_Position = light_matrix * M * inst_m * vec4(position, 1.0);
}
