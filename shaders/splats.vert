#version 330 core
// One instanced quad per primitive: EWA projection exactly as docs/METHOD.md and
// renderer/_torch_ref.py `project`. FRUSTUM_SLACK is #defined by renderer/gl/programs.py.

uniform sampler2DArray u_params;  // per-primitive parameters; layers as in renderer/gl/splats.py
uniform mat3 u_rotation;          // world-to-camera rotation (OpenCV: x right, y down, z forward)
uniform vec3 u_translation;       // world-to-camera translation
uniform vec2 u_focal;             // fx, fy in pixels
uniform vec2 u_principal;         // cx, cy in pixels, pixel centres at integers
uniform vec2 u_size;              // image width, height in pixels (the viewport)
uniform float u_eps2d;            // screen-space dilation added to the 2D covariance, px^2

in uint in_index;                 // the primitive this instance draws (instances in depth order)

out vec2 v_offset;                // pixel-centre offset from the projected mean, in pixels
flat out vec3 v_conic;            // inverse 2D covariance (xx, xy, yy)
flat out vec4 v_shape;            // opacity, a, t, support u_s
flat out vec3 v_color;

vec4 fetch(int layer) {
    int width = textureSize(u_params, 0).x;
    int i = int(in_index);
    return texelFetch(u_params, ivec3(i % width, i / width, layer), 0);
}

// Rotation of a (w, x, y, z) quaternion of any norm; the zero quaternion gives the identity.
mat3 quat_to_rotation(vec4 quat) {
    vec4 q = quat / sqrt(max(dot(quat, quat), 1e-24));
    float w = q.x, x = q.y, y = q.z, z = q.w;
    return transpose(mat3(  // rows, transposed into GLSL's column-major storage
        1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - w * z), 2.0 * (x * z + w * y),
        2.0 * (x * y + w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - w * x),
        2.0 * (x * z - w * y), 2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y)));
}

bool finite(vec2 v) {
    return !any(isnan(v)) && !any(isinf(v));
}

void main() {
    vec4 mean_opacity = fetch(0);
    vec4 scale_a = fetch(1);
    vec4 quat = fetch(2);
    vec4 t_support = fetch(3);
    v_color = fetch(4).rgb;

    // Camera space. Primitives at z <= near never get here: the CPU leaves them out of the order.
    vec3 p = u_rotation * mean_opacity.xyz + u_translation;
    // Jacobian of the projection at the direction clamped to FRUSTUM_SLACK half fields of view.
    vec2 limit = FRUSTUM_SLACK * 0.5 * u_size / u_focal;
    vec2 tangent = clamp(p.xy / p.z, -limit, limit);
    vec3 j0 = u_focal.x / p.z * vec3(1.0, 0.0, -tangent.x);
    vec3 j1 = u_focal.y / p.z * vec3(0.0, 1.0, -tangent.y);
    // Rows of J R_cam R_q S, so that the 2D covariance is M M^T (row vector * matrix in GLSL).
    mat3 rq = quat_to_rotation(quat);
    vec3 m0 = (j0 * u_rotation * rq) * scale_a.xyz;
    vec3 m1 = (j1 * u_rotation * rq) * scale_a.xyz;
    float cxx = dot(m0, m0), cyy = dot(m1, m1);
    // det(M M^T) = |m0 x m1|^2 (Cauchy-Binet) has no cancellation, unlike cxx cyy - cxy^2 in
    // float32 for a long thin primitive (the training kernel uses float64 for this instead).
    vec3 normal = cross(m0, m1);
    float det = dot(normal, normal) + u_eps2d * (cxx + cyy) + u_eps2d * u_eps2d;
    vec2 diagonal = vec2(cxx, cyy) + u_eps2d;
    v_conic = vec3(diagonal.y, -dot(m0, m1), diagonal.x) / det;
    v_shape = vec4(mean_opacity.w, scale_a.w, t_support.xy);

    vec2 mean2d = u_focal * p.xy / p.z + u_principal;
    // Support box half-widths sqrt(2 a u_s cov_xx), sqrt(2 a u_s cov_yy), plus one pixel so
    // that float rounding never clips a pixel: the fragment's u <= u_s test is the exact bound.
    vec2 extent = sqrt(2.0 * scale_a.w * t_support.y * diagonal) + 1.0;
    vec2 corner = vec2(gl_VertexID & 1, gl_VertexID >> 1) * 2.0 - 1.0;  // triangle strip
    v_offset = corner * extent;
    vec2 pixel = mean2d + v_offset;
    if (!finite(pixel) || !finite(v_conic.xz) || !finite(vec2(v_conic.y, det))) {
        gl_Position = vec4(0.0, 0.0, 2.0, 1.0);  // beyond the far plane: the quad is clipped
        return;
    }
    // Pixel centre (x, y) lies at window (x + 0.5, height - y - 0.5): image row 0 at the top.
    gl_Position = vec4(2.0 * (pixel.x + 0.5) / u_size.x - 1.0, 1.0 - 2.0 * (pixel.y + 0.5) / u_size.y,
                       0.0, 1.0);
}
