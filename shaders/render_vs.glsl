// render_vs.glsl - vertex stage of every render mode.
// Without tessellation the vertex is placed here (sc_surface at its own uv);
// with tessellation it passes the base position and uv on to the TCS/TES.
// SC_WELD (the crack check's welded pass, see render.c) places every corner
// of a vertex at the one uv a_weld_uv gives them all, and passes the welded
// uvs of each face's edges (a_edge_uv: the canonical side's uvs at this
// corner and the next) on to the TES.
layout(location = 0) in vec3 a_position;
layout(location = 1) in vec2 a_uv;
layout(location = 2) in vec2 a_weld_uv;
layout(location = 3) in vec4 a_edge_uv;

#ifdef SC_TESS
out vec3 tc_base;
out vec2 tc_uv;
out vec2 tc_weld_uv;
out vec4 tc_edge_uv;

void main() {
    tc_base = a_position;
    tc_uv = a_uv;
    tc_weld_uv = a_weld_uv;
    tc_edge_uv = a_edge_uv;
}
#else
uniform mat4 u_view_proj;
out vec3 v_world;
out vec2 v_uv;

void main() {
#ifdef SC_WELD
    v_world = sc_surface(a_position, a_weld_uv);
#else
    v_world = sc_surface(a_position, a_uv);
#endif
    v_uv = a_uv;
    gl_Position = u_view_proj * vec4(v_world, 1.0);
}
#endif
