// seam_vs.glsl - the seam-gap probe for the untessellated modes. One point
// per invocation: a seam half-edge's endpoints (the same surface positions
// for both sides, each side with its own uvs) and a parameter t. The point is
// placed by sc_surface exactly as the render's vertex stage places a vertex,
// at the blended base position and uv; t = 0 and t = 1 are the vertices
// themselves. Captured with transform feedback; nothing is drawn.
layout(location = 0) in vec3 a_p0;
layout(location = 1) in vec3 a_p1;
layout(location = 2) in vec2 a_uv0;
layout(location = 3) in vec2 a_uv1;
layout(location = 4) in float a_t;
out vec3 f_pos;

void main() {
    float t = a_t;
    float s = 1.0 - t;
    precise vec3 base = s * a_p0 + t * a_p1;
    precise vec2 uv = s * a_uv0 + t * a_uv1;
    f_pos = sc_surface(base, uv);
    gl_Position = vec4(0.0, 0.0, 0.0, 1.0);
}
