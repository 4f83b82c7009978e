#version 330 core
// Depth only (the shadow maps).
// Derived from pyrender's shaders/mesh_depth.frag (MIT License, Copyright (c) 2019 Matthew Matl).

out vec4 frag_color;

void main()
{
    frag_color = vec4(1.0);
}
