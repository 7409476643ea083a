// render_tes.glsl - evaluation at each generated vertex (Liu et al. 2017 §7):
// the base position and uv are the barycentric blend of the patch's corners,
// then sc_surface samples the geometry image or adds the displacement there.
// `precise` forbids fused multiply-adds, so on an edge (one weight 0) both
// faces compute a*x + b*y from the same rounded products: the same bits.
// v_world, f_coord and f_patch are also what the seam-gap check captures with
// transform feedback from this very program.
layout(triangles, equal_spacing, ccw) in;

in vec3 te_base[];
in vec2 te_uv[];
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
    v_world = sc_surface(base, uv);
    v_uv = uv;
    f_coord = c;
    f_patch = u_patch_base + gl_PrimitiveID;
    gl_Position = u_view_proj * vec4(v_world, 1.0);
}
