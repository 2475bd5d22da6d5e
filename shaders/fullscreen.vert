#version 330 core
// One triangle covering the viewport; uv runs 0..1 with v = 0 at the bottom (GL convention).
out vec2 uv;
void main() {
    vec2 p = vec2(float((gl_VertexID << 1) & 2), float(gl_VertexID & 2));
    uv = p;
    gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);
}
