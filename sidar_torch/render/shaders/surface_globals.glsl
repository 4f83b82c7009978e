
vec3 specular_light = vec3(0.0);  // specular light reflected towards the camera, unshadowed
