#version 330 core
// The lens's resampling pass (render.resample): one triangle covering the viewport, no vertex data
// (vertices 0, 1, 2 at clip (-1, -1), (3, -1), (-1, 3)); every output pixel is one fragment.
void main()
{
    vec2 corner = vec2((gl_VertexID << 1) & 2, gl_VertexID & 2);
    gl_Position = vec4(corner * 2.0 - 1.0, 0.0, 1.0);
}
