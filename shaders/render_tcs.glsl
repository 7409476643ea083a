// render_tcs.glsl - uniform tessellation: every outer and inner level is
// u_level, so the two faces of an edge always split it the same way.
layout(vertices = 3) out;

in vec3 tc_base[];
in vec2 tc_uv[];
in vec2 tc_weld_uv[];
in vec4 tc_edge_uv[];
out vec3 te_base[];
out vec2 te_uv[];
out vec2 te_weld_uv[];
out vec4 te_edge_uv[];

uniform float u_level;

void main() {
    te_base[gl_InvocationID] = tc_base[gl_InvocationID];
    te_uv[gl_InvocationID] = tc_uv[gl_InvocationID];
    te_weld_uv[gl_InvocationID] = tc_weld_uv[gl_InvocationID];
    te_edge_uv[gl_InvocationID] = tc_edge_uv[gl_InvocationID];
    if (gl_InvocationID == 0) {
        gl_TessLevelOuter[0] = u_level;
        gl_TessLevelOuter[1] = u_level;
        gl_TessLevelOuter[2] = u_level;
        gl_TessLevelInner[0] = u_level;
    }
}
