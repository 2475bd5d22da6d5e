#version 330 core
in vec4 colour;
out vec4 frag;
void main() {
    frag = colour;
}
