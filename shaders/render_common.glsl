// render_common.glsl - what every render stage shares: where a surface point
// is. Prepended (after #version and the defines) to each stage.
//
// SC_POS selects the position source, exactly as the render modes define it:
//   0  the base mesh position (textured);
//   1  the geometry image at uv (positions in .xyz);
//   2  the base position plus the vector displacement map at uv.
// Textures are sampled with textureLod(.., 0): bilinear, no mipmaps, the
// wrap mode of the asset (a sampler object), texel (i, j) centred at
// ((i + 1/2)/W, (j + 1/2)/H) and row 0 at v = 0: docs/design.md's convention is
// GL's own, so uvs go in untouched.
#ifndef SC_POS
#define SC_POS 0
#endif

layout(binding = 1) uniform sampler2D u_geometry;
layout(binding = 2) uniform sampler2D u_displacement;

vec3 sc_surface(vec3 base, vec2 uv) {
#if SC_POS == 1
    return textureLod(u_geometry, uv, 0.0).xyz;
#elif SC_POS == 2
    precise vec3 p = base + textureLod(u_displacement, uv, 0.0).xyz;
    return p;
#else
    return base;
#endif
}
