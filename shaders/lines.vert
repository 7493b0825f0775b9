#version 330 core
// Polylines, camera frusta and points in world space.

uniform mat4 u_view_projection;  // world -> clip space (renderer/gl/camera.py `gl_projection` @ w2c)
uniform float u_point_size;      // pixels, for points

in vec3 in_position;
in vec4 in_color;

out vec4 v_color;

void main() {
    gl_Position = u_view_projection * vec4(in_position, 1.0);
    gl_PointSize = u_point_size;
    v_color = in_color;
}
