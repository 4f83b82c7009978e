#version 330 core
// The camera-frame pass: with CAMERA_DEPTH the fragment's distance along the camera's axis, with
// CAMERA_NORMALS its unit normal in the OpenCV camera frame (x right, y down, z forward), into a
// float target; the target's clear value (0) stays where nothing is drawn.

#ifdef CAMERA_DEPTH
in float camera_depth;
#endif
#ifdef CAMERA_NORMALS
in vec3 camera_normal;
#endif
out vec4 frag_value;

void main()
{
#ifdef CAMERA_DEPTH
    frag_value = vec4(camera_depth, 0.0, 0.0, 1.0);
#endif
#ifdef CAMERA_NORMALS
    vec3 n = normalize(camera_normal);
    frag_value = vec4(n.x, -n.y, -n.z, 1.0);  // OpenGL's camera frame (y up, looking along -z) to OpenCV's
#endif
}
