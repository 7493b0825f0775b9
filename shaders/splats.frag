#version 330 core
// The DoG footprint D(u; t) and the alpha rule of docs/METHOD.md, with the same branches as
// csrc/dog_profile.h. ALPHA_MIN, ALPHA_MAX, NEAR_LOG_T and SERIES_LIMIT are #defined by
// renderer/gl/programs.py from renderer/config.py and renderer/_torch_ref.py.

in vec2 v_offset;
flat in vec3 v_conic;
flat in vec4 v_shape;  // opacity, a, t, support u_s
flat in vec3 v_color;

out vec4 f_color;

// (exp(x) - 1) / x, with its Taylor series near 0.
float phi(float x) {
    if (abs(x) < SERIES_LIMIT) {
        return 1.0 + x * (1.0 / 2.0 + x * (1.0 / 6.0 + x * (1.0 / 24.0 + x * (1.0 / 120.0))));
    }
    return (exp(x) - 1.0) / x;
}

// D(u; t) = [exp(-u) - t exp(-t u)] / (1 - t); near t = 1 the form without 0/0.
float dog(float u, float t) {
    float s = 1.0 - t;
    if (s >= NEAR_LOG_T) {
        return (exp(-u) - t * exp(-t * u)) / s;
    }
    return exp(-t * u) - u * exp(-u) * phi(s * u);
}

void main() {
    vec2 d = v_offset;
    float q = v_conic.x * d.x * d.x + 2.0 * v_conic.y * d.x * d.y + v_conic.z * d.y * d.y;
    float u = q * (0.5 / v_shape.y);
    // Negated comparisons also discard NaN.
    if (!(u <= v_shape.w)) {
        discard;
    }
    float alpha = min(ALPHA_MAX, v_shape.x * dog(u, v_shape.z));
    if (!(alpha >= ALPHA_MIN)) {
        discard;
    }
    // Premultiplied; blended front to back ("under"): C += (1 - A) c alpha, A += (1 - A) alpha.
    f_color = vec4(v_color * alpha, alpha);
}
