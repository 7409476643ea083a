/* sc_imageio.c - the C side of image I/O: loads the codec module on first use,
 * and keeps the latest large PNG encodings of image values, so that one
 * texture written by two nodes of a cook is deflated once.
 *
 * Design note: see sc_imageio_codecs.h for why the codecs are a module. The
 * module is looked for, in order: $SEAMCOOK_IMAGEIO_MODULE; beside the running
 * executable; in the library folder of its installation (SC_IMAGEIO_INSTALL_DIR,
 * relative to the executable's folder, as /proc/self/exe names it: an
 * installed tree can move as a whole); in the build folder it was built in.
 * It is opened once
 * (pthread_once), with RTLD_LOCAL so its hundreds of libraries stay out of the
 * global namespace; a missing module is an error naming the places searched.
 */
#include "sc_imageio.h"

#include <dlfcn.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "sc_imageio_codecs.h"

const sc_kernel sc_kernel_imageio = {"imageio", SC_IMAGEIO_VERSION, NULL};

static pthread_once_t load_once = PTHREAD_ONCE_INIT;
static const sc_imageio_codecs *codecs;
static char load_error[1024];

static const sc_imageio_codecs *try_open(const char *path) {
    void *module = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!module) {
        snprintf(load_error, sizeof load_error, "%s", dlerror());
        return NULL;
    }
    const sc_imageio_codecs *(*get)(void) = (const sc_imageio_codecs *(*)(void))dlsym(module, SC_IMAGEIO_ENTRY);
    const sc_imageio_codecs *c = get ? get() : NULL;
    if (!c || c->abi != SC_IMAGEIO_ABI) {
        snprintf(load_error, sizeof load_error, "%s: not a seamcook image module of version %d", path,
                 SC_IMAGEIO_ABI);
        dlclose(module);
        return NULL;
    }
    return c;   /* stays loaded for the life of the process */
}

/* Open the module in folder `dir` (joined to `base` when not NULL), if it is there. */
static bool open_in(const char *base, const char *dir) {
    char *folder = base ? sc_path_join(base, dir) : sc_strdup(dir);
    char *path = folder ? sc_path_join(folder, SC_IMAGEIO_MODULE) : NULL;
    if (path && access(path, R_OK) == 0) codecs = try_open(path);
    free(folder), free(path);
    return codecs != NULL;
}

static void load_codecs(void) {
    const char *env = getenv("SEAMCOOK_IMAGEIO_MODULE");
    if (env && *env && (codecs = try_open(env))) return;
    char self[4096];
    ssize_t n = readlink("/proc/self/exe", self, sizeof self - 1);
    char *exe_dir = NULL;
    if (n > 0) {
        self[n] = 0;
        exe_dir = sc_path_dirname(self);
    }
    bool found = exe_dir && open_in(exe_dir, ".");
#ifdef SC_IMAGEIO_INSTALL_DIR
    found = found || (exe_dir && open_in(exe_dir, SC_IMAGEIO_INSTALL_DIR));
#endif
#ifdef SC_IMAGEIO_BUILD_DIR
    found = found || open_in(NULL, SC_IMAGEIO_BUILD_DIR);
#endif
    free(exe_dir);
    if (!found && !load_error[0])
        snprintf(load_error, sizeof load_error,
                 "%s not found beside the executable, in its installation's library folder or in the build folder",
                 SC_IMAGEIO_MODULE);
}

static const sc_imageio_codecs *get_codecs(sc_error *err) {
    pthread_once(&load_once, load_codecs);
    if (!codecs) sc_fail(err, SC_EIO, "image codecs unavailable: %s", load_error);
    return codecs;
}

const char *sc_image_sniff(const void *bytes, size_t size) { return sc_imageio_sniff(bytes, size); }

int sc_image_decode(const char *name, const void *bytes, size_t size, sc_image_data **out, sc_error *err) {
    *out = NULL;
    bool declined = true;
    int rc = sc_imageio_png_decode(name, bytes, size, out, &declined, err);
    if (rc != SC_OK || !declined) return rc;
    const sc_imageio_codecs *c = get_codecs(err);
    return c ? c->decode(name, bytes, size, out, err) : SC_EIO;
}

int sc_image_encode_png(const sc_image_data *im, int bits, sc_buf *out, sc_error *err) {
    return sc_imageio_png_encode(im, bits, out, err);
}

/* Remembered PNG encodings: a few, oldest first, under one lock held only
 * to look up, copy or insert (the encoding itself runs outside it; two
 * threads that miss at once both encode the same bytes, and one is kept). */
#define REMEMBERED 16
typedef struct remembered {
    sc_digest digest;
    int bits;
    uint8_t *bytes;
    size_t len;
} remembered;
static pthread_mutex_t remember_lock = PTHREAD_MUTEX_INITIALIZER;
static remembered kept[REMEMBERED];
static int nkept;
static size_t kept_bytes;
static int64_t remembered_hits;

static int find_kept(const sc_digest *d, int bits) {
    for (int i = 0; i < nkept; i++)
        if (kept[i].bits == bits && sc_digest_equal(&kept[i].digest, d)) return i;
    return -1;
}

static void drop_oldest(void) {
    kept_bytes -= kept[0].len;
    free(kept[0].bytes);
    memmove(kept, kept + 1, sizeof *kept * (size_t)(nkept - 1));
    nkept--;
}

int sc_image_value_encode_png(const sc_value *image, int bits, sc_buf *out, sc_error *err) {
    if (image->kind != SC_KIND_IMAGE) return sc_fail(err, SC_EUSAGE, "encoding a PNG: not an image value");
    const sc_image_data *im = image->as.image;
    size_t pixels = (size_t)im->width * (size_t)im->height * (size_t)im->channels * (size_t)im->pixel;
    if (pixels < SC_IMAGE_REMEMBER_MIN) return sc_image_encode_png(im, bits, out, err);
    const sc_digest *d = sc_value_digest(image);
    pthread_mutex_lock(&remember_lock);
    int at = find_kept(d, bits);
    if (at >= 0) {
        sc_buf_append(out, kept[at].bytes, kept[at].len);
        remembered_hits++;
    }
    pthread_mutex_unlock(&remember_lock);
    if (at >= 0) return out->failed ? sc_fail(err, SC_ENOMEM, "out of memory") : SC_OK;
    size_t start = out->len;
    int rc = sc_image_encode_png(im, bits, out, err);
    size_t len = out->len - start;
    if (rc != SC_OK || out->failed || len > SC_IMAGE_REMEMBER_MAX) return rc;
    uint8_t *copy = malloc(len);
    if (!copy) return SC_OK;   /* only the memory is missed */
    memcpy(copy, out->data + start, len);
    pthread_mutex_lock(&remember_lock);
    if (find_kept(d, bits) >= 0) {
        free(copy);
    } else {
        while (nkept > 0 && (nkept == REMEMBERED || kept_bytes + len > SC_IMAGE_REMEMBER_MAX)) drop_oldest();
        kept[nkept++] = (remembered){*d, bits, copy, len};
        kept_bytes += len;
    }
    pthread_mutex_unlock(&remember_lock);
    return SC_OK;
}

int64_t sc_image_remembered_hits(void) {
    pthread_mutex_lock(&remember_lock);
    int64_t hits = remembered_hits;
    pthread_mutex_unlock(&remember_lock);
    return hits;
}

int sc_image_encode_jpeg(const sc_image_data *im, int quality, sc_buf *out, sc_error *err) {
    const sc_imageio_codecs *c = get_codecs(err);
    return c ? c->encode_jpeg(im, quality, out, err) : SC_EIO;
}


int sc_image_decode_levels(const char *name, const void *bytes, size_t size, sc_image_data ***levels,
                           int *nlevels, sc_error *err) {
    *levels = NULL;
    *nlevels = 0;
    const sc_imageio_codecs *c = get_codecs(err);
    return c ? c->decode_levels(name, bytes, size, levels, nlevels, err) : SC_EIO;
}
