/* sc_gl.h - a headless OpenGL 4.5 core context over EGL, and the few GL
 * helpers the render node needs (programs, framebuffers, textures).
 *
 * One context per call: sc_gl_open makes a new context current on the calling
 * thread; sc_gl_close releases and destroys it. Nothing needs a window, X, or
 * environment variables. Where EGL lists a software device
 * (EGL_MESA_device_software) that device is used, so that the pictures are
 * the same on every machine; otherwise the Mesa surfaceless platform.
 *
 * Every failure is an sc_error; nothing here aborts.
 */
#ifndef SC_GL_H
#define SC_GL_H

#include <GL/gl.h>
#include <GL/glext.h>

#include "sc_value.h"

/* Bump whenever results of this library can change for the same inputs:
 * every node listing sc_kernel_gl (or a kernel built on it) is re-keyed. */
#define SC_GL_VERSION 1
extern const sc_kernel sc_kernel_gl;

typedef struct sc_gl sc_gl;

/* A new GL 4.5 core context, current on this thread. Fails cleanly (SC_EIO)
 * when EGL or a suitable context is missing. */
int sc_gl_open(sc_gl **out, sc_error *err);
/* Release and destroy the context (NULL is fine). */
void sc_gl_close(sc_gl *gl);
/* GL_RENDERER of the context, e.g. "llvmpipe (LLVM 15.0.6, 256 bits)". */
const char *sc_gl_renderer(const sc_gl *gl);

/* SC_OK when glGetError has nothing to say, else an error naming `what`. */
int sc_gl_check(const char *what, sc_error *err);

/* ---------------------------------------------------------------- programs */

/* One shader stage made of up to 7 source strings concatenated in order
 * (e.g. "#version", defines, a common file, the stage's file). `label` names
 * the stage's file in messages. */
typedef struct sc_gl_stage {
    GLenum type;                 /* GL_VERTEX_SHADER, ... ; 0 ends a list */
    const char *label;
    const char *parts[7];        /* NULL-terminated */
} sc_gl_stage;

/* Compile and link the stages into *out. feedback: names of outputs to
 * capture with transform feedback (interleaved), or NULL. A failure gives the
 * compiler's or linker's log in the message. */
int sc_gl_program(const char *name, const sc_gl_stage *stages, int nstages,
                  const char *const *feedback, int nfeedback, GLuint *out, sc_error *err);

/* ---------------------------------------------------------------- targets */

/* An offscreen framebuffer: colour (RGBA8) and a 32-bit float depth buffer. */
typedef struct sc_gl_target {
    GLuint fbo, color, depth;
    int32_t width, height;
} sc_gl_target;

int sc_gl_target_create(sc_gl_target *t, int32_t width, int32_t height, sc_error *err);
void sc_gl_target_destroy(sc_gl_target *t);
/* Read back the colour attachment (width*height*4 bytes, RGBA) and the depth
 * buffer (width*height floats in [0, 1]), bottom row first. Either may be
 * NULL. */
int sc_gl_target_read(const sc_gl_target *t, uint8_t *rgba, float *depth, sc_error *err);

/* ---------------------------------------------------------------- textures */

/* Upload an image as a 2D texture without mipmaps: u8 -> RGBA8-style
 * normalised, u16 -> 16-bit normalised, f32 -> 32-bit float. Rows go in as
 * stored (bottom-up, GL's order), so texel (i, j) has its centre at
 * ((i + 1/2)/W, (j + 1/2)/H). One and two channel images read as (r, r, r, 1)
 * and (r, r, r, g). Filtering and wrapping come from a sampler
 * (sc_gl_sampler), not from the texture. */
int sc_gl_texture(const sc_image_data *im, GLuint *out, sc_error *err);

/* A sampler with bilinear filtering, no mipmaps, and the given wrap modes. */
int sc_gl_sampler(sc_wrap wrap_u, sc_wrap wrap_v, GLuint *out, sc_error *err);

#endif
