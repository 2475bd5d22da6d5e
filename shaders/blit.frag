#version 330 core
// Copies the finished view (image + overlays + outlines) to its region of the window.
in vec2 uv;
out vec4 frag;
uniform sampler2D view_tex;
void main() {
    frag = vec4(texture(view_tex, uv).rgb, 1.0);
}
