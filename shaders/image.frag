#version 330 core
// The traced image: tone-mapped colour, optionally blended with an overlay colour map.
// Textures hold image row 0 in their first row, so v is flipped to put row 0 at the top.
//
// Variants are chosen with #defines (viewer/display.py inserts them after #version):
// Mesa's llvmpipe runs both sides of every branch, so unused paths must not be compiled.
//   TONE      tone mapping on (exposure, Reinhard, gamma); off: the identity
//   OVERLAY   show the channel in data_tex through the colour map
//   LOG_SCALE the overlay's values are mapped on a log scale
in vec2 uv;
out vec4 frag;

uniform sampler2D colour_tex;   // RGB32F shaded colour, display-ready sRGB (tracer.shade)
uniform sampler2D data_tex;     // RG32F: overlay channel value (NaN: undefined), special class (0: none)
uniform sampler2D lut_tex;      // 256x1 RGB32F colour map (tracer.colormap.table)

uniform float exposure;         // stops, applied in linear light: colour * 2^exposure
uniform float gamma;            // extra display gamma (1: none)
uniform int tone;               // 0 clamp, 1 Reinhard
uniform float opacity;
uniform float lo;
uniform float hi;
uniform vec3 special_colour[4]; // fixed colours of the channel's special classes 1..4

#ifdef TONE
vec3 srgb_to_linear(vec3 c) {
    return mix(c / 12.92, pow((c + 0.055) / 1.055, vec3(2.4)), step(vec3(0.04045), c));
}

vec3 linear_to_srgb(vec3 c) {
    return mix(12.92 * c, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, step(vec3(0.0031308), c));
}
#endif

vec3 tone_map(vec3 c) {
    c = clamp(c, 0.0, 1.0);
#ifdef TONE
    c = srgb_to_linear(c) * exp2(exposure);
    if (tone == 1) c = c / (1.0 + c);
    c = pow(linear_to_srgb(clamp(c, 0.0, 1.0)), vec3(1.0 / gamma));
#endif
    return c;  // without TONE the window shows exactly what the CLI writes
}

#ifdef OVERLAY
vec3 colour_map(float value) {
#ifdef LOG_SCALE
    float a = log(max(lo, 1e-30)), b = log(max(hi, 1e-30));
    float v = log(max(value, max(lo, 1e-30)));
#else
    float a = lo, b = hi, v = value;
#endif
    float s = b > a ? clamp((v - a) / (b - a), 0.0, 1.0) : 0.5;
    return texelFetch(lut_tex, ivec2(int(s * 255.0 + 0.5), 0), 0).rgb;  // nearest, as the CLI's maps
}
#endif

void main() {
    vec2 st = vec2(uv.x, 1.0 - uv.y);
    vec3 base = tone_map(texture(colour_tex, st).rgb);
#ifdef OVERLAY
    vec2 d = texture(data_tex, st).rg;
    int k = int(d.g + 0.5);
    if (k > 0) base = mix(base, special_colour[min(k, 4) - 1], opacity);
    else if (!isnan(d.r)) base = mix(base, colour_map(d.r), opacity);
#endif
    frag = vec4(base, 1.0);
}
