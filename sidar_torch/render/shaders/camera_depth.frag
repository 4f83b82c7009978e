#version 330 core
// The camera-depth pass: the fragment's distance along the camera's axis, into a float target.

in float camera_depth;
out vec4 frag_depth;

void main()
{
    frag_depth = vec4(camera_depth, 0.0, 0.0, 1.0);
}
