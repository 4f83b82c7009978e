#version 330 core
// One flat colour per draw (the mask draw).
// Derived from pyrender's shaders/segmentation.frag (MIT License, Copyright (c) 2019 Matthew Matl).

uniform vec3 color;
out vec4 frag_color;

///////////////////////////////////////////////////////////////////////////////
// MAIN
///////////////////////////////////////////////////////////////////////////////
void main()
{
    frag_color = vec4(color, 1.0);
    //frag_color = vec4(1.0, 0.5, 0.5, 1.0);
}
