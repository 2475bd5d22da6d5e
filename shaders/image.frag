#version 330 core
// The traced image: tone-mapped colour, optionally blended with an overlay colour map.
// Textures hold image row 0 in their first row, so v is flipped to put row 0 at the top.
in vec2 uv;
out vec4 frag;

uniform sampler2D colour_tex;   // RGB32F shaded colour (display-ready, before exposure)
uniform sampler2D data_tex;     // RG32F: overlay channel value (NaN: undefined), special class (0: none)
uniform sampler2D lut_tex;      // 256x1 RGB32F colour map (tracer.colormap.table)

uniform float exposure;         // stops, applied in linear light: colour * 2^exposure
uniform float gamma;            // extra display gamma (1: none)
uniform int tone;               // 0 clamp, 1 Reinhard
uniform int overlay;            // 0 none, 1 show the channel in data_tex
uniform float opacity;
uniform int log_scale;
uniform float lo;
uniform float hi;
uniform vec3 special_colour[4]; // fixed colours of the channel's special classes 1..4

vec3 srgb_to_linear(vec3 c) {
    return mix(c / 12.92, pow((c + 0.055) / 1.055, vec3(2.4)), step(vec3(0.04045), c));
}

vec3 linear_to_srgb(vec3 c) {
    return mix(12.92 * c, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, step(vec3(0.0031308), c));
}

// The colour texture is display-ready sRGB (tracer.shade); with exposure 0, clamp and
// gamma 1 this is the identity, so the window shows exactly what the CLI writes.
vec3 tone_map(vec3 c) {
    if (exposure == 0.0 && tone == 0 && gamma == 1.0) return clamp(c, 0.0, 1.0);
    c = srgb_to_linear(clamp(c, 0.0, 1.0)) * exp2(exposure);
    if (tone == 1) c = c / (1.0 + c);
    c = linear_to_srgb(clamp(c, 0.0, 1.0));
    return pow(c, vec3(1.0 / gamma));
}

vec3 colour_map(float value) {
    float a = lo, b = hi, v = value;
    if (log_scale == 1) {
        a = log(max(lo, 1e-30));
        b = log(max(hi, 1e-30));
        v = log(max(value, max(lo, 1e-30)));
    }
    float s = b > a ? clamp((v - a) / (b - a), 0.0, 1.0) : 0.5;
    return texelFetch(lut_tex, ivec2(int(s * 255.0 + 0.5), 0), 0).rgb;  // nearest, as the CLI's maps
}

void main() {
    vec2 st = vec2(uv.x, 1.0 - uv.y);
    vec3 base = tone_map(texture(colour_tex, st).rgb);
    vec4 d = texture(data_tex, st);
    vec3 over = base;
    bool show = false;
    if (overlay == 1) {
        int k = int(d.g + 0.5);
        if (k > 0) { over = special_colour[min(k, 4) - 1]; show = true; }
        else if (!isnan(d.r)) { over = colour_map(d.r); show = true; }
    }
    frag = vec4(show ? mix(base, over, opacity) : base, 1.0);
}
