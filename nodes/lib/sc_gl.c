/* sc_gl.c - headless OpenGL 4.5 core over EGL (see sc_gl.h).
 *
 * Design note.
 *  - Display: EGL 1.5 client extensions only, no environment variables.
 *    When EGL_EXT_device_enumeration lists a device with
 *    EGL_MESA_device_software, its device-platform display is used (the same
 *    llvmpipe rasteriser everywhere, so pictures are reproducible even on a
 *    machine with a GPU); otherwise Mesa's surfaceless platform. Plain
 *    eglGetDisplay(EGL_DEFAULT_DISPLAY) is never used: it tries X11.
 *  - Contexts: one per sc_gl_open, configless where EGL_KHR_no_config_context
 *    is offered, current with no surface (EGL_KHR_surfaceless_context); all
 *    drawing goes to framebuffer objects.
 *  - The display is the process's: eglInitialize/eglTerminate act on it for
 *    every thread at once (EGL without EGL_KHR_display_reference does not
 *    count them), so a terminate at the end of one render would pull the
 *    display from under a render running on another thread. It is therefore
 *    initialised once, under a mutex, and never terminated: the driver stays
 *    loaded like any other shared library, and each render still gets a
 *    context of its own, destroyed when it ends. This also saves loading
 *    llvmpipe again on every render (docs/notes/render.md), and keeps the
 *    memory Mesa holds reachable (after eglTerminate, LeakSanitizer reports
 *    Mesa's leftovers from the unloaded driver as leaks). The display handle
 *    is the only shared state; it never reaches any output.
 */
#include "sc_gl.h"

#include <EGL/egl.h>
#include <EGL/eglext.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const char *gl_platform(void);
const sc_kernel sc_kernel_gl = {"gl", SC_GL_VERSION, NULL, gl_platform};

struct sc_gl {
    EGLDisplay display;
    EGLContext context;
    char renderer[256];
    char version[128];
};

static pthread_mutex_t display_lock = PTHREAD_MUTEX_INITIALIZER;
static EGLDisplay shared_display = EGL_NO_DISPLAY;

static const char *egl_error_name(EGLint e) {
    switch (e) {
    case EGL_SUCCESS: return "EGL_SUCCESS";
    case EGL_NOT_INITIALIZED: return "EGL_NOT_INITIALIZED";
    case EGL_BAD_ACCESS: return "EGL_BAD_ACCESS";
    case EGL_BAD_ALLOC: return "EGL_BAD_ALLOC";
    case EGL_BAD_ATTRIBUTE: return "EGL_BAD_ATTRIBUTE";
    case EGL_BAD_CONFIG: return "EGL_BAD_CONFIG";
    case EGL_BAD_CONTEXT: return "EGL_BAD_CONTEXT";
    case EGL_BAD_CURRENT_SURFACE: return "EGL_BAD_CURRENT_SURFACE";
    case EGL_BAD_DISPLAY: return "EGL_BAD_DISPLAY";
    case EGL_BAD_MATCH: return "EGL_BAD_MATCH";
    case EGL_BAD_NATIVE_PIXMAP: return "EGL_BAD_NATIVE_PIXMAP";
    case EGL_BAD_NATIVE_WINDOW: return "EGL_BAD_NATIVE_WINDOW";
    case EGL_BAD_PARAMETER: return "EGL_BAD_PARAMETER";
    case EGL_BAD_SURFACE: return "EGL_BAD_SURFACE";
    case EGL_CONTEXT_LOST: return "EGL_CONTEXT_LOST";
    default: return "unknown EGL error";
    }
}

/* Whether a space-separated extension list holds `name` as a whole word. */
static bool has_extension(const char *list, const char *name) {
    size_t n = strlen(name);
    for (const char *p = list; p && *p;) {
        while (*p == ' ') p++;
        const char *end = strchr(p, ' ');
        size_t len = end ? (size_t)(end - p) : strlen(p);
        if (len == n && memcmp(p, name, n) == 0) return true;
        p += len;
    }
    return false;
}

/* The software device's display, or EGL_NO_DISPLAY. */
static EGLDisplay software_device_display(const char *client,
                                          PFNEGLGETPLATFORMDISPLAYEXTPROC get_display) {
    if (!has_extension(client, "EGL_EXT_device_enumeration") ||
        !has_extension(client, "EGL_EXT_platform_device"))
        return EGL_NO_DISPLAY;
    PFNEGLQUERYDEVICESEXTPROC query_devices =
        (PFNEGLQUERYDEVICESEXTPROC)eglGetProcAddress("eglQueryDevicesEXT");
    PFNEGLQUERYDEVICESTRINGEXTPROC query_string =
        (PFNEGLQUERYDEVICESTRINGEXTPROC)eglGetProcAddress("eglQueryDeviceStringEXT");
    if (!query_devices || !query_string) return EGL_NO_DISPLAY;
    EGLDeviceEXT devices[32];
    EGLint count = 0;
    if (!query_devices(32, devices, &count)) return EGL_NO_DISPLAY;
    for (EGLint i = 0; i < count; i++) {
        const char *ext = query_string(devices[i], EGL_EXTENSIONS);
        if (has_extension(ext, "EGL_MESA_device_software"))
            return get_display(EGL_PLATFORM_DEVICE_EXT, devices[i], NULL);
    }
    return EGL_NO_DISPLAY;
}

/* The process's display, initialised by the first caller. Called with
 * display_lock held. */
static int acquire_display(EGLDisplay *out, sc_error *err) {
    if (shared_display != EGL_NO_DISPLAY) {
        *out = shared_display;
        return SC_OK;
    }
    const char *client = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
    if (!client)
        return sc_fail(err, SC_EIO, "EGL: no client extensions (needs EGL 1.5 or "
                                    "EGL_EXT_client_extensions; install libegl1 and libegl-mesa0)");
    PFNEGLGETPLATFORMDISPLAYEXTPROC get_display =
        (PFNEGLGETPLATFORMDISPLAYEXTPROC)eglGetProcAddress("eglGetPlatformDisplayEXT");
    if (!get_display || !has_extension(client, "EGL_EXT_platform_base"))
        return sc_fail(err, SC_EIO, "EGL: eglGetPlatformDisplayEXT is missing");
    EGLint major = 0, minor = 0;
    EGLDisplay d = software_device_display(client, get_display);
    if (d != EGL_NO_DISPLAY && !eglInitialize(d, &major, &minor)) d = EGL_NO_DISPLAY;
    if (d == EGL_NO_DISPLAY) {
        if (!has_extension(client, "EGL_MESA_platform_surfaceless"))
            return sc_fail(err, SC_EIO, "EGL: neither a software device nor Mesa's surfaceless "
                                        "platform is available (install libegl-mesa0)");
        d = get_display(EGL_PLATFORM_SURFACELESS_MESA, (void *)EGL_DEFAULT_DISPLAY, NULL);
        if (d == EGL_NO_DISPLAY)
            return sc_fail(err, SC_EIO, "EGL: no surfaceless display (%s)", egl_error_name(eglGetError()));
        if (!eglInitialize(d, &major, &minor))
            return sc_fail(err, SC_EIO, "EGL: eglInitialize failed (%s)", egl_error_name(eglGetError()));
    }
    shared_display = d;
    *out = d;
    return SC_OK;
}

static int create_context(sc_gl *gl, sc_error *err) {
    const char *ext = eglQueryString(gl->display, EGL_EXTENSIONS);
    if (!has_extension(ext, "EGL_KHR_surfaceless_context"))
        return sc_fail(err, SC_EIO, "EGL: the display lacks EGL_KHR_surfaceless_context");
    if (!eglBindAPI(EGL_OPENGL_API))
        return sc_fail(err, SC_EIO, "EGL: desktop OpenGL is not available (%s)",
                       egl_error_name(eglGetError()));
    EGLConfig config = EGL_NO_CONFIG_KHR;
    if (!has_extension(ext, "EGL_KHR_no_config_context")) {
        const EGLint want[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_NONE};
        EGLint n = 0;
        if (!eglChooseConfig(gl->display, want, &config, 1, &n) || n < 1)
            return sc_fail(err, SC_EIO, "EGL: no config renders OpenGL");
    }
    const EGLint attribs[] = {EGL_CONTEXT_MAJOR_VERSION, 4, EGL_CONTEXT_MINOR_VERSION, 5,
                              EGL_CONTEXT_OPENGL_PROFILE_MASK, EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
                              EGL_NONE};
    gl->context = eglCreateContext(gl->display, config, EGL_NO_CONTEXT, attribs);
    if (gl->context == EGL_NO_CONTEXT)
        return sc_fail(err, SC_EIO, "EGL: no OpenGL 4.5 core context (%s)", egl_error_name(eglGetError()));
    if (!eglMakeCurrent(gl->display, EGL_NO_SURFACE, EGL_NO_SURFACE, gl->context))
        return sc_fail(err, SC_EIO, "EGL: eglMakeCurrent failed (%s)", egl_error_name(eglGetError()));
    const char *renderer = (const char *)glGetString(GL_RENDERER);
    const char *version = (const char *)glGetString(GL_VERSION);
    snprintf(gl->renderer, sizeof gl->renderer, "%s", renderer ? renderer : "unknown");
    snprintf(gl->version, sizeof gl->version, "%s", version ? version : "unknown");
    return SC_OK;
}

int sc_gl_open(sc_gl **out, sc_error *err) {
    *out = NULL;
    sc_gl *gl = calloc(1, sizeof *gl);
    if (!gl) return sc_fail(err, SC_ENOMEM, "out of memory");
    gl->context = EGL_NO_CONTEXT;
    pthread_mutex_lock(&display_lock);
    int rc = acquire_display(&gl->display, err);
    pthread_mutex_unlock(&display_lock);
    if (rc == SC_OK) rc = create_context(gl, err);
    if (rc != SC_OK) {
        sc_gl_close(gl);
        return rc;
    }
    *out = gl;
    return SC_OK;
}

void sc_gl_close(sc_gl *gl) {
    if (!gl) return;
    if (gl->context != EGL_NO_CONTEXT) {
        eglMakeCurrent(gl->display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
        eglDestroyContext(gl->display, gl->context);
    }
    eglReleaseThread();
    free(gl);
}

const char *sc_gl_renderer(const sc_gl *gl) { return gl ? gl->renderer : ""; }

/* The kernel's platform text: GL_RENDERER and GL_VERSION of a context made
 * once per process ("llvmpipe (LLVM 15.0.6, 256 bits); 4.5 (Core Profile)
 * Mesa 22.3.6"): the driver's version and the rasteriser's vector width
 * decide the pictures' bits. Without a display it says so, and render then
 * fails on its own with the reason. */
static char platform_text[400];

static void platform_find(void) {
    sc_gl *gl;
    sc_error err;
    if (sc_gl_open(&gl, &err) != SC_OK) {
        snprintf(platform_text, sizeof platform_text, "no display");
        return;
    }
    snprintf(platform_text, sizeof platform_text, "%s; %s", gl->renderer, gl->version);
    sc_gl_close(gl);
}

static const char *gl_platform(void) {
    static pthread_once_t once = PTHREAD_ONCE_INIT;
    pthread_once(&once, platform_find);
    return platform_text;
}

static const char *gl_error_name(GLenum e) {
    switch (e) {
    case GL_INVALID_ENUM: return "GL_INVALID_ENUM";
    case GL_INVALID_VALUE: return "GL_INVALID_VALUE";
    case GL_INVALID_OPERATION: return "GL_INVALID_OPERATION";
    case GL_INVALID_FRAMEBUFFER_OPERATION: return "GL_INVALID_FRAMEBUFFER_OPERATION";
    case GL_OUT_OF_MEMORY: return "GL_OUT_OF_MEMORY";
    case GL_STACK_OVERFLOW: return "GL_STACK_OVERFLOW";
    case GL_STACK_UNDERFLOW: return "GL_STACK_UNDERFLOW";
    default: return "unknown GL error";
    }
}

int sc_gl_check(const char *what, sc_error *err) {
    GLenum e = glGetError(), first = e;
    if (e == GL_NO_ERROR) return SC_OK;
    while (e != GL_NO_ERROR) e = glGetError();   /* drain */
    return sc_fail(err, first == GL_OUT_OF_MEMORY ? SC_ENOMEM : SC_EIO, "OpenGL: %s failed (%s)", what,
                   gl_error_name(first));
}

/* ---------------------------------------------------------------- programs */

static const char *stage_name(GLenum type) {
    switch (type) {
    case GL_VERTEX_SHADER: return "vertex";
    case GL_TESS_CONTROL_SHADER: return "tessellation control";
    case GL_TESS_EVALUATION_SHADER: return "tessellation evaluation";
    case GL_GEOMETRY_SHADER: return "geometry";
    case GL_FRAGMENT_SHADER: return "fragment";
    default: return "unknown";
    }
}

/* The log of a shader or program, trimmed to fit in a message. */
static void info_log(GLuint object, bool program, char *out, size_t n) {
    GLsizei len = 0;
    out[0] = 0;
    if (program) glGetProgramInfoLog(object, (GLsizei)n, &len, out);
    else glGetShaderInfoLog(object, (GLsizei)n, &len, out);
    if (len < 0) len = 0;
    if ((size_t)len >= n) len = (GLsizei)n - 1;
    out[len] = 0;
    while (len > 0 && (out[len - 1] == '\n' || out[len - 1] == ' ')) out[--len] = 0;
}

int sc_gl_program(const char *name, const sc_gl_stage *stages, int nstages,
                  const char *const *feedback, int nfeedback, GLuint *out, sc_error *err) {
    *out = 0;
    char log[768];
    GLuint program = glCreateProgram();
    GLuint shaders[8] = {0};
    int nshaders = 0, rc = SC_OK;
    if (!program) return sc_fail(err, SC_EIO, "OpenGL: glCreateProgram failed for %s", name);
    for (int s = 0; s < nstages && s < 8; s++) {
        const sc_gl_stage *st = &stages[s];
        int nparts = 0;
        while (nparts < 7 && st->parts[nparts]) nparts++;
        GLuint sh = glCreateShader(st->type);
        if (!sh) {
            rc = sc_fail(err, SC_EIO, "OpenGL: cannot create a %s shader for %s", stage_name(st->type), name);
            break;
        }
        shaders[nshaders++] = sh;
        glShaderSource(sh, nparts, st->parts, NULL);
        glCompileShader(sh);
        GLint ok = 0;
        glGetShaderiv(sh, GL_COMPILE_STATUS, &ok);
        if (!ok) {
            info_log(sh, false, log, sizeof log);
            rc = sc_fail(err, SC_EIO, "shader %s (%s stage of %s) does not compile: %s", st->label,
                         stage_name(st->type), name, log);
            break;
        }
        glAttachShader(program, sh);
    }
    if (rc == SC_OK) {
        if (feedback && nfeedback > 0)
            glTransformFeedbackVaryings(program, nfeedback, feedback, GL_INTERLEAVED_ATTRIBS);
        glLinkProgram(program);
        GLint ok = 0;
        glGetProgramiv(program, GL_LINK_STATUS, &ok);
        if (!ok) {
            info_log(program, true, log, sizeof log);
            rc = sc_fail(err, SC_EIO, "shader program %s does not link: %s", name, log);
        }
    }
    for (int s = 0; s < nshaders; s++) {
        if (rc == SC_OK) glDetachShader(program, shaders[s]);
        glDeleteShader(shaders[s]);
    }
    if (rc != SC_OK) {
        glDeleteProgram(program);
        return rc;
    }
    *out = program;
    return sc_gl_check(name, err);
}

/* ---------------------------------------------------------------- targets */

int sc_gl_target_create(sc_gl_target *t, int32_t width, int32_t height, sc_error *err) {
    memset(t, 0, sizeof *t);
    GLint max_size = 0;
    glGetIntegerv(GL_MAX_RENDERBUFFER_SIZE, &max_size);
    if (width < 1 || height < 1 || width > max_size || height > max_size)
        return sc_fail(err, SC_EINPUT, "render target %dx%d is beyond the GL limit %d", width, height,
                       max_size);
    t->width = width;
    t->height = height;
    GLuint rb[2];
    glGenRenderbuffers(2, rb);
    t->color = rb[0], t->depth = rb[1];
    /* colour is written sRGB-encoded (GL_FRAMEBUFFER_SRGB): shaders work in
     * linear light, the way sRGB textures are filtered, and the picture
     * holds what a display shows */
    const GLenum formats[2] = {GL_SRGB8_ALPHA8, GL_DEPTH_COMPONENT32F};
    for (int i = 0; i < 2; i++) {
        glBindRenderbuffer(GL_RENDERBUFFER, rb[i]);
        glRenderbufferStorage(GL_RENDERBUFFER, formats[i], width, height);
    }
    glBindRenderbuffer(GL_RENDERBUFFER, 0);
    glGenFramebuffers(1, &t->fbo);
    glBindFramebuffer(GL_FRAMEBUFFER, t->fbo);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, t->color);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, t->depth);
    glDrawBuffer(GL_COLOR_ATTACHMENT0);
    glEnable(GL_FRAMEBUFFER_SRGB);
    GLenum status = glCheckFramebufferStatus(GL_FRAMEBUFFER);
    int rc = sc_gl_check("creating a framebuffer", err);
    if (rc == SC_OK && status != GL_FRAMEBUFFER_COMPLETE)
        rc = sc_fail(err, SC_EIO, "OpenGL: framebuffer %dx%d is incomplete (0x%x)", width, height,
                     (unsigned)status);
    if (rc != SC_OK) sc_gl_target_destroy(t);
    return rc;
}

void sc_gl_target_destroy(sc_gl_target *t) {
    if (t->fbo) glDeleteFramebuffers(1, &t->fbo);
    GLuint rb[2] = {t->color, t->depth};
    glDeleteRenderbuffers(2, rb);
    memset(t, 0, sizeof *t);
}

int sc_gl_target_read(const sc_gl_target *t, uint8_t *rgba, float *depth, sc_error *err) {
    glBindFramebuffer(GL_READ_FRAMEBUFFER, t->fbo);
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    glReadBuffer(GL_COLOR_ATTACHMENT0);
    if (rgba) glReadPixels(0, 0, t->width, t->height, GL_RGBA, GL_UNSIGNED_BYTE, rgba);
    if (depth) glReadPixels(0, 0, t->width, t->height, GL_DEPTH_COMPONENT, GL_FLOAT, depth);
    return sc_gl_check("reading back a render", err);
}

/* ---------------------------------------------------------------- textures */

int sc_gl_texture(const sc_image_data *im, GLuint *out, sc_error *err) {
    *out = 0;
    if (!im || !im->pixels || im->channels < 1 || im->channels > 4 || im->width < 1 || im->height < 1)
        return sc_fail(err, SC_EINPUT, "texture: malformed image");
    /* sRGB colour is sampled as linear light, as an engine samples it: 8-bit
     * RGB(A) in an sRGB format (decoded before filtering), any other sRGB
     * image decoded here into a float texture */
    bool srgb = im->colorspace == SC_COLOR_SRGB;
    if (srgb && !(im->pixel == SC_PIXEL_U8 && im->channels >= 3)) {
        sc_image_data *lin = sc_image_to_linear_f32(im, 1);
        if (!lin) return sc_fail(err, SC_ENOMEM, "out of memory");
        int rc = sc_gl_texture(lin, out, err);
        sc_image_free(lin);
        return rc;
    }
    GLint max_size = 0;
    glGetIntegerv(GL_MAX_TEXTURE_SIZE, &max_size);
    if (im->width > max_size || im->height > max_size)
        return sc_fail(err, SC_EINPUT, "texture %dx%d is beyond the GL limit %d", im->width, im->height,
                       max_size);
    static const GLenum formats[4] = {GL_RED, GL_RG, GL_RGB, GL_RGBA};
    GLenum format = formats[im->channels - 1], type, internal;
    switch (im->pixel) {
    case SC_PIXEL_U8:
        type = GL_UNSIGNED_BYTE;
        internal = srgb ? (im->channels == 3 ? GL_SRGB8 : GL_SRGB8_ALPHA8)
                   : im->channels == 1 ? GL_R8
                   : im->channels == 2 ? GL_RG8
                                       : GL_RGBA8;
        break;
    case SC_PIXEL_U16:
        type = GL_UNSIGNED_SHORT;
        internal = im->channels == 1 ? GL_R16 : im->channels == 2 ? GL_RG16 : GL_RGBA16;
        break;
    case SC_PIXEL_F32:
        type = GL_FLOAT;
        internal = im->channels == 1 ? GL_R32F : im->channels == 2 ? GL_RG32F : GL_RGBA32F;
        break;
    default: return sc_fail(err, SC_EINPUT, "texture: unknown pixel type %d", (int)im->pixel);
    }
    GLuint tex = 0;
    glGenTextures(1, &tex);
    glBindTexture(GL_TEXTURE_2D, tex);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    glTexImage2D(GL_TEXTURE_2D, 0, (GLint)internal, im->width, im->height, 0, format, type, im->pixels);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_BASE_LEVEL, 0);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAX_LEVEL, 0);
    if (im->channels <= 2) {
        const GLint swizzle[2][4] = {{GL_RED, GL_RED, GL_RED, GL_ONE}, {GL_RED, GL_RED, GL_RED, GL_GREEN}};
        glTexParameteriv(GL_TEXTURE_2D, GL_TEXTURE_SWIZZLE_RGBA, swizzle[im->channels - 1]);
    }
    glBindTexture(GL_TEXTURE_2D, 0);
    int rc = sc_gl_check("uploading a texture", err);
    if (rc != SC_OK) {
        glDeleteTextures(1, &tex);
        return rc;
    }
    *out = tex;
    return SC_OK;
}

static GLint gl_wrap(sc_wrap w) {
    switch (w) {
    case SC_WRAP_CLAMP: return GL_CLAMP_TO_EDGE;
    case SC_WRAP_MIRROR: return GL_MIRRORED_REPEAT;
    case SC_WRAP_REPEAT:
    default: return GL_REPEAT;
    }
}

int sc_gl_sampler(sc_wrap wrap_u, sc_wrap wrap_v, GLuint *out, sc_error *err) {
    GLuint s = 0;
    glGenSamplers(1, &s);
    glSamplerParameteri(s, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
    glSamplerParameteri(s, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    glSamplerParameteri(s, GL_TEXTURE_WRAP_S, gl_wrap(wrap_u));
    glSamplerParameteri(s, GL_TEXTURE_WRAP_T, gl_wrap(wrap_v));
    int rc = sc_gl_check("creating a sampler", err);
    if (rc != SC_OK) {
        glDeleteSamplers(1, &s);
        return rc;
    }
    *out = s;
    return SC_OK;
}
