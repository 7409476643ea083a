// render_fs.glsl - shading for the crack check. Front faces: the colour
// texture (or a light grey) lit by a key light and a little ambient, alpha 1.
// Back faces: pure red with alpha 1/2 (the crack counter reads alpha, never
// the colour, so a red texture is never a crack; the background clears to
// alpha 0; PNGs drop alpha). One RGBA8 target: a second, integer
// attachment costs llvmpipe noticeably more shading (docs/notes/render.md).
// Back faces are pushed back by a tiny depth bias so that rounding at a
// silhouette never lets a back face win over the front face it folds under;
// a real crack shows surface far behind, which the bias does not hide.
in vec3 v_world;
in vec2 v_uv;
layout(location = 0) out vec4 o_color;

layout(binding = 0) uniform sampler2D u_color;
uniform int u_has_color;     // 0: no colour texture, use grey
uniform vec3 u_light;        // unit vector towards the key light
uniform vec3 u_eye_dir;      // unit vector towards the viewer (orthographic)
uniform float u_back_bias;   // depth bias for back faces

void main() {
    if (!gl_FrontFacing) {
        o_color = vec4(1.0, 0.0, 0.0, 0.5);
        gl_FragDepth = min(gl_FragCoord.z + u_back_bias, 1.0);
        return;
    }
    // Shading works in linear light: sRGB textures decode when sampled, and
    // the target encodes to sRGB when written.
    gl_FragDepth = gl_FragCoord.z;
    vec3 albedo = u_has_color != 0 ? texture(u_color, v_uv).rgb : vec3(0.7);
    vec3 n = cross(dFdx(v_world), dFdy(v_world));
    float len = length(n);
    n = len > 0.0 ? n / len : u_eye_dir;
    if (dot(n, u_eye_dir) < 0.0) n = -n;
    float light = 0.3 + 0.7 * max(dot(n, u_light), 0.0);
    o_color = vec4(albedo * light, 1.0);
}
