// render_vs.glsl - vertex stage of every render mode.
// Without tessellation the vertex is placed here (sc_surface at its own uv);
// with tessellation it passes the base position and uv on to the TCS/TES.
layout(location = 0) in vec3 a_position;
layout(location = 1) in vec2 a_uv;

#ifdef SC_TESS
out vec3 tc_base;
out vec2 tc_uv;

void main() {
    tc_base = a_position;
    tc_uv = a_uv;
}
#else
uniform mat4 u_view_proj;
out vec3 v_world;
out vec2 v_uv;

void main() {
    v_world = sc_surface(a_position, a_uv);
    v_uv = a_uv;
    gl_Position = u_view_proj * vec4(v_world, 1.0);
}
#endif
