#version 330 core
// Box outlines: world-space edge endpoints projected with the tracer's pinhole camera.
in vec3 in_position;
in vec4 in_colour;
out vec4 colour;
uniform mat4 view_projection;
void main() {
    colour = in_colour;
    gl_Position = view_projection * vec4(in_position, 1.0);
}
