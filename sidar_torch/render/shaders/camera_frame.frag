#version 330 core
// The camera-frame pass: with CAMERA_DEPTH the fragment's distance along the camera's axis, into a
// float target; the target's clear value (0) stays where nothing is drawn.

#ifdef CAMERA_DEPTH
in float camera_depth;
#endif
out vec4 frag_value;

void main()
{
#ifdef CAMERA_DEPTH
    frag_value = vec4(camera_depth, 0.0, 0.0, 1.0);
#endif
}
