// render_tes.glsl - evaluation at each generated vertex (Liu et al. 2017 §7):
// the base position and uv are the barycentric blend of the patch's corners,
// then sc_surface samples the geometry image or adds the displacement there.
// `precise` forbids fused multiply-adds, so on an edge (one weight 0) both
// faces compute a*x + b*y from the same rounded products: the same bits.
// v_world, f_coord and f_patch are also what the seam-gap check captures with
// transform feedback from this very program.
// SC_WELD (the crack check's welded pass): a corner samples at its vertex's
// one welded uv, a point on an edge at the blend of the edge's canonical
// uvs (te_edge_uv[i]: the edge from corner i to corner i + 1), so both faces
// of a seam place it from the same products, and no seam can open.
layout(triangles, equal_spacing, ccw) in;

in vec3 te_base[];
in vec2 te_uv[];
in vec2 te_weld_uv[];
in vec4 te_edge_uv[];
out vec3 v_world;
out vec2 v_uv;
out vec3 f_coord;
flat out int f_patch;

uniform mat4 u_view_proj;
uniform int u_patch_base;    // first patch of this draw (gl_PrimitiveID restarts per draw)

void main() {
    vec3 c = gl_TessCoord;
    precise vec3 base = c.x * te_base[0] + c.y * te_base[1] + c.z * te_base[2];
    precise vec2 uv = c.x * te_uv[0] + c.y * te_uv[1] + c.z * te_uv[2];
#ifdef SC_WELD
    precise vec2 at = uv;
    if (c.x == 1.0) at = te_weld_uv[0];
    else if (c.y == 1.0) at = te_weld_uv[1];
    else if (c.z == 1.0) at = te_weld_uv[2];
    else if (c.z == 0.0) at = c.x * te_edge_uv[0].xy + c.y * te_edge_uv[0].zw;
    else if (c.x == 0.0) at = c.y * te_edge_uv[1].xy + c.z * te_edge_uv[1].zw;
    else if (c.y == 0.0) at = c.z * te_edge_uv[2].xy + c.x * te_edge_uv[2].zw;
    v_world = sc_surface(base, at);
#else
    v_world = sc_surface(base, uv);
#endif
    v_uv = uv;
    f_coord = c;
    f_patch = u_patch_base + gl_PrimitiveID;
    gl_Position = u_view_proj * vec4(v_world, 1.0);
}
