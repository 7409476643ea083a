/* sc_value.c - immutable, content-addressed values.
 *
 * Design note: a value's digest is the SHA-256 of its canonical bytes, and the
 * canonical bytes of a composite (atlas, lods, report) name its parts by
 * digest only. So a node that changes only the mesh of an atlas makes a new
 * atlas whose textures are the very same IMAGE values: nothing is copied or
 * re-hashed. The digest is computed once, when the value is made, by streaming
 * the same bytes that sc_value_serialize writes through the hasher (large
 * arrays are never copied just to be hashed).
 *
 * Encoding: "SCV" + kind byte + u32 format, then the kind's fields, all little
 * endian. Pixel and coordinate arrays are written as their in-memory bytes,
 * which is little endian on every host seamcook builds for (checked below).
 */
#include "sc_value.h"

#include <math.h>
#include <sched.h>
#include <stdlib.h>
#include <stdio.h>
#include <string.h>

#if !defined(__BYTE_ORDER__) || __BYTE_ORDER__ != __ORDER_LITTLE_ENDIAN__
#error "seamcook's value encoding assumes a little-endian host"
#endif

static const char *const kind_names[] = {"none", "mesh", "image", "atlas", "lods", "report", "bytes"};
#define NKINDS ((int)(sizeof kind_names / sizeof kind_names[0]))

const char *sc_kind_name(sc_kind k) {
    return ((int)k >= 0 && (int)k < NKINDS) ? kind_names[k] : "none";
}

sc_kind sc_kind_from_name(const char *name) {
    for (int k = 1; k < NKINDS; k++)
        if (strcmp(kind_names[k], name) == 0) return (sc_kind)k;
    return SC_KIND_NONE;
}

const char *sc_wrap_name(sc_wrap w) {
    switch (w) {
    case SC_WRAP_REPEAT: return "repeat";
    case SC_WRAP_CLAMP: return "clamp";
    case SC_WRAP_MIRROR: return "mirror";
    }
    return "repeat";
}

/* ---------------------------------------------------------------- mesh */

sc_mesh *sc_mesh_alloc(int32_t nv, int32_t nu, int32_t nn, int32_t nf, int32_t nmat) {
    if (nv < 0 || nu < 0 || nn < 0 || nf < 0 || nmat < 1) return NULL;
    sc_mesh *m = calloc(1, sizeof *m);
    if (!m) return NULL;
    m->nv = nv, m->nu = nu, m->nn = nn, m->nf = nf, m->nmat = nmat;
    /* +1 keeps every array non-NULL even when a count is 0 */
    m->V = calloc((size_t)nv * 3 + 1, sizeof(double));
    m->U = calloc((size_t)nu * 2 + 1, sizeof(double));
    m->FV = calloc((size_t)nf * 3 + 1, sizeof(int32_t));
    m->FU = calloc((size_t)nf * 3 + 1, sizeof(int32_t));
    m->FM = calloc((size_t)nf + 1, sizeof(int32_t));
    m->materials = calloc((size_t)nmat, sizeof(char *));
    if (nn > 0) {
        m->N = calloc((size_t)nn * 3, sizeof(double));
        m->FN = calloc((size_t)nf * 3 + 1, sizeof(int32_t));
    }
    if (!m->V || !m->U || !m->FV || !m->FU || !m->FM || !m->materials ||
        (nn > 0 && (!m->N || !m->FN))) {
        sc_mesh_free(m);
        return NULL;
    }
    return m;
}

void sc_mesh_free(sc_mesh *m) {
    if (!m) return;
    free(m->V), free(m->U), free(m->N);
    free(m->FV), free(m->FU), free(m->FN), free(m->FM);
    if (m->materials)
        for (int32_t i = 0; i < m->nmat; i++) free(m->materials[i]);
    free(m->materials);
    free(m);
}

int sc_mesh_check(const sc_mesh *m, sc_error *err) {
    for (int64_t i = 0; i < (int64_t)m->nv * 3; i++)
        if (!isfinite(m->V[i]))
            return sc_fail(err, SC_EINPUT, "vertex %lld: coordinate is not finite",
                           (long long)(i / 3 + 1));
    for (int64_t i = 0; i < (int64_t)m->nu * 2; i++)
        if (!isfinite(m->U[i]))
            return sc_fail(err, SC_EINPUT, "uv %lld: coordinate is not finite",
                           (long long)(i / 2 + 1));
    for (int64_t i = 0; i < (int64_t)m->nn * 3; i++)
        if (!isfinite(m->N[i]))
            return sc_fail(err, SC_EINPUT, "normal %lld: coordinate is not finite",
                           (long long)(i / 3 + 1));
    for (int32_t f = 0; f < m->nf; f++) {
        const int32_t *fv = m->FV + 3 * f, *fu = m->FU + 3 * f;
        for (int k = 0; k < 3; k++) {
            if (fv[k] < 0 || fv[k] >= m->nv)
                return sc_fail(err, SC_EINPUT, "face %d: vertex index %d out of range [1, %d]",
                               f + 1, fv[k] + 1, m->nv);
            if (fu[k] < 0 || fu[k] >= m->nu)
                return sc_fail(err, SC_EINPUT, "face %d: uv index %d out of range [1, %d]",
                               f + 1, fu[k] + 1, m->nu);
            if (m->FN && (m->FN[3 * f + k] < 0 || m->FN[3 * f + k] >= m->nn))
                return sc_fail(err, SC_EINPUT, "face %d: normal index %d out of range [1, %d]",
                               f + 1, m->FN[3 * f + k] + 1, m->nn);
        }
        if (fv[0] == fv[1] || fv[1] == fv[2] || fv[0] == fv[2])
            return sc_fail(err, SC_EINPUT, "face %d: repeats a vertex (degenerate)", f + 1);
        if (m->FM[f] < 0 || m->FM[f] >= m->nmat)
            return sc_fail(err, SC_EINPUT, "face %d: material %d out of range", f + 1, m->FM[f]);
    }
    return SC_OK;
}

/* ---------------------------------------------------------------- image */

sc_image_data *sc_image_alloc(int32_t w, int32_t h, int32_t c, sc_pixel pixel) {
    if (w < 1 || h < 1 || c < 1 || c > 4 || w > SC_IMAGE_MAX_SIDE || h > SC_IMAGE_MAX_SIDE ||
        (uint64_t)w * (uint64_t)h > SC_IMAGE_MAX_PIXELS)
        return NULL;
    if (pixel != SC_PIXEL_U8 && pixel != SC_PIXEL_U16 && pixel != SC_PIXEL_F32) return NULL;
    sc_image_data *im = calloc(1, sizeof *im);
    if (!im) return NULL;
    im->width = w, im->height = h, im->channels = c, im->pixel = pixel;
    im->colorspace = pixel == SC_PIXEL_F32 ? SC_COLOR_LINEAR : SC_COLOR_SRGB;
    im->pixels = calloc((size_t)w * (size_t)h * (size_t)c, (size_t)pixel);
    if (!im->pixels) {
        free(im);
        return NULL;
    }
    return im;
}

void sc_image_free(sc_image_data *im) {
    if (!im) return;
    free(im->pixels);
    free(im);
}

static size_t image_bytes(const sc_image_data *im) {
    return (size_t)im->width * (size_t)im->height * (size_t)im->channels * (size_t)im->pixel;
}

float sc_image_texel(const sc_image_data *im, int32_t i, int32_t j, int32_t c) {
    size_t k = ((size_t)j * (size_t)im->width + (size_t)i) * (size_t)im->channels + (size_t)c;
    switch (im->pixel) {
    case SC_PIXEL_U8: return ((const uint8_t *)im->pixels)[k] * (1.0f / 255.0f);
    case SC_PIXEL_U16: return ((const uint16_t *)im->pixels)[k] * (1.0f / 65535.0f);
    case SC_PIXEL_F32: return ((const float *)im->pixels)[k];
    }
    return 0;
}

float sc_srgb_to_linear(float c) { return c <= 0.04045f ? c / 12.92f : powf((c + 0.055f) / 1.055f, 2.4f); }

float sc_linear_to_srgb(float c) {
    if (!(c > 0)) return 0;
    if (c >= 1) return 1;
    return c <= 0.0031308f ? 12.92f * c : 1.055f * powf(c, 1 / 2.4f) - 0.055f;
}

bool sc_channel_is_alpha(int32_t channels, int32_t c) { return (channels == 2 && c == 1) || (channels == 4 && c == 3); }

typedef struct to_f32_job {
    const sc_image_data *in;
    float *dst;
    size_t n;
    const float *lut;   /* linear: each stored 8/16-bit value's linear light; NULL: as stored */
    bool linear;        /* colour channels through the sRGB curve */
} to_f32_job;

#define TO_F32_CHUNK ((size_t)1 << 20)

static int to_f32_chunk(void *ud, int32_t chunk) {
    const to_f32_job *j = ud;
    size_t k0 = (size_t)chunk * TO_F32_CHUNK, k1 = k0 + TO_F32_CHUNK < j->n ? k0 + TO_F32_CHUNK : j->n;
    float *dst = j->dst;
    const int32_t C = j->in->channels;
    bool colour[4];   /* per channel: through the sRGB curve */
    for (int32_t c = 0; c < C && c < 4; c++) colour[c] = j->linear && !sc_channel_is_alpha(C, c);
    bool any_colour = false;
    for (int32_t c = 0; c < C && c < 4; c++) any_colour |= colour[c];
    if (!any_colour) {   /* every sample as stored: loops the compiler vectorises */
        if (j->in->pixel == SC_PIXEL_F32) {
            memcpy(dst + k0, (const float *)j->in->pixels + k0, (k1 - k0) * sizeof *dst);
        } else if (j->in->pixel == SC_PIXEL_U8) {
            const uint8_t *src = j->in->pixels;
            for (size_t k = k0; k < k1; k++) dst[k] = src[k] * (1.0f / 255.0f);
        } else {
            const uint16_t *src = j->in->pixels;
            for (size_t k = k0; k < k1; k++) dst[k] = src[k] * (1.0f / 65535.0f);
        }
        return SC_OK;
    }
    int32_t c = (int32_t)(k0 % (size_t)C);   /* the channel of sample k */
    if (j->in->pixel == SC_PIXEL_F32) {
        const float *src = j->in->pixels;
        for (size_t k = k0; k < k1; k++, c = c + 1 == C ? 0 : c + 1)
            dst[k] = colour[c] ? sc_srgb_to_linear(src[k]) : src[k];
    } else if (j->in->pixel == SC_PIXEL_U8) {
        float plain[256];   /* a channel as stored */
        for (int v = 0; v < 256; v++) plain[v] = v * (1.0f / 255.0f);
        const float *table[4];
        for (int32_t ch = 0; ch < C && ch < 4; ch++) table[ch] = colour[ch] ? j->lut : plain;
        const uint8_t *src = j->in->pixels;
        for (size_t k = k0; k < k1; k++, c = c + 1 == C ? 0 : c + 1) dst[k] = table[c][src[k]];
    } else {
        const uint16_t *src = j->in->pixels;
        for (size_t k = k0; k < k1; k++, c = c + 1 == C ? 0 : c + 1)
            dst[k] = colour[c] ? j->lut[src[k]] : src[k] * (1.0f / 65535.0f);
    }
    return SC_OK;
}

sc_image_data *sc_image_to_f32(const sc_image_data *im) { return sc_image_to_f32_threads(im, 1); }

sc_image_data *sc_image_to_f32_threads(const sc_image_data *im, int threads) {
    sc_image_data *out = sc_image_alloc(im->width, im->height, im->channels, SC_PIXEL_F32);
    if (!out) return NULL;
    out->colorspace = im->colorspace;
    memcpy(out->format, im->format, sizeof out->format);
    to_f32_job j = {im, out->pixels, (size_t)im->width * (size_t)im->height * (size_t)im->channels, NULL, false};
    int32_t chunks = (int32_t)((j.n + TO_F32_CHUNK - 1) / TO_F32_CHUNK);
    if (sc_parallel(threads, chunks, to_f32_chunk, &j) != SC_OK)
        for (int32_t c = 0; c < chunks; c++) to_f32_chunk(&j, c);
    return out;
}

float *sc_srgb_decode_table(sc_pixel pixel) {
    int32_t levels = pixel == SC_PIXEL_U8 ? 256 : pixel == SC_PIXEL_U16 ? 65536 : 0;
    float *table = levels ? malloc((size_t)levels * sizeof *table) : NULL;
    for (int32_t v = 0; table && v < levels; v++) table[v] = sc_srgb_to_linear(v * (1.0f / (float)(levels - 1)));
    return table;
}

sc_image_data *sc_image_to_linear_f32(const sc_image_data *im, int threads) {
    if (im->colorspace != SC_COLOR_SRGB) return sc_image_to_f32_threads(im, threads);
    sc_image_data *out = sc_image_alloc(im->width, im->height, im->channels, SC_PIXEL_F32);
    float *lut = im->pixel != SC_PIXEL_F32 ? sc_srgb_decode_table(im->pixel) : NULL;
    if (!out || (im->pixel != SC_PIXEL_F32 && !lut)) {
        sc_image_free(out), free(lut);
        return NULL;
    }
    out->colorspace = SC_COLOR_LINEAR;
    memcpy(out->format, im->format, sizeof out->format);
    to_f32_job j = {im, out->pixels, (size_t)im->width * (size_t)im->height * (size_t)im->channels, lut, true};
    int32_t chunks = (int32_t)((j.n + TO_F32_CHUNK - 1) / TO_F32_CHUNK);
    if (sc_parallel(threads, chunks, to_f32_chunk, &j) != SC_OK)
        for (int32_t c = 0; c < chunks; c++) to_f32_chunk(&j, c);
    free(lut);
    return out;
}

/* ---------------------------------------------------------------- atlas, lods, report */

sc_atlas *sc_atlas_new(sc_value *mesh) {
    sc_atlas *a = calloc(1, sizeof *a);
    if (!a) {
        sc_value_release(mesh);
        return NULL;
    }
    a->mesh = mesh;
    return a;
}

int sc_atlas_add_texture(sc_atlas *a, const char *name, int32_t material, sc_wrap wrap_u,
                         sc_wrap wrap_v, const char *source, sc_value *image) {
    sc_texture *t = realloc(a->textures, sizeof *t * (size_t)(a->ntex + 1));
    if (!t) {
        sc_value_release(image);
        return SC_ENOMEM;
    }
    a->textures = t;
    t += a->ntex;
    memset(t, 0, sizeof *t);
    t->name = sc_strdup(name);
    t->source = sc_strdup(source ? source : "");
    t->material = material;
    t->wrap_u = wrap_u, t->wrap_v = wrap_v;
    t->image = image;
    a->ntex++;
    if (!t->name || !t->source) return SC_ENOMEM;
    return SC_OK;
}

sc_material sc_material_default(void) {
    return (sc_material){.base_color = {1, 1, 1, 1}, .metallic = 1, .roughness = 1, .normal_scale = 1,
                         .occlusion_strength = 1, .alpha_cutoff = 0.5, .alpha_mode = SC_ALPHA_OPAQUE};
}

sc_material sc_atlas_material(const sc_atlas *a, int32_t material) {
    if (a->materials) return a->materials[material];
    sc_material c = sc_material_default();
    c.metallic = sc_atlas_find_texture(a, material, "metallic_roughness") >= 0 ? 1 : 0;
    double e = sc_atlas_find_texture(a, material, "emissive") >= 0 ? 1 : 0;
    c.emissive[0] = c.emissive[1] = c.emissive[2] = e;
    return c;
}

int sc_atlas_copy_materials(sc_atlas *dst, const sc_atlas *src) {
    free(dst->materials);
    dst->materials = NULL;
    if (!src->materials) return SC_OK;
    int32_t n = src->mesh->as.mesh->nmat;
    dst->materials = malloc((size_t)(n > 0 ? n : 1) * sizeof *dst->materials);
    if (!dst->materials) return SC_ENOMEM;
    memcpy(dst->materials, src->materials, (size_t)n * sizeof *dst->materials);
    return SC_OK;
}

void sc_atlas_free(sc_atlas *a) {
    if (!a) return;
    free(a->materials);
    sc_value_release(a->mesh);
    for (int32_t i = 0; i < a->ntex; i++) {
        free(a->textures[i].name);
        free(a->textures[i].source);
        sc_value_release(a->textures[i].image);
    }
    free(a->textures);
    free(a);
}

int sc_atlas_find_texture(const sc_atlas *a, int32_t material, const char *name) {
    for (int32_t i = 0; i < a->ntex; i++)
        if (a->textures[i].material == material && strcmp(a->textures[i].name, name) == 0)
            return i;
    return -1;
}

sc_lods *sc_lods_new(void) { return calloc(1, sizeof(sc_lods)); }

int sc_lods_add(sc_lods *l, sc_value *atlas) {
    sc_value **p = realloc(l->levels, sizeof *p * (size_t)(l->count + 1));
    if (!p) {
        sc_value_release(atlas);
        return SC_ENOMEM;
    }
    l->levels = p;
    l->levels[l->count++] = atlas;
    return SC_OK;
}

void sc_lods_free(sc_lods *l) {
    if (!l) return;
    for (int32_t i = 0; i < l->count; i++) sc_value_release(l->levels[i]);
    free(l->levels);
    free(l);
}

sc_report *sc_report_new(void) { return calloc(1, sizeof(sc_report)); }

int sc_metric_list_add(sc_metric_list *l, const char *name, double value) {
    if (l->count == l->cap) {
        int32_t cap = l->cap ? 2 * l->cap : 16;
        sc_metric *items = realloc(l->items, sizeof *items * (size_t)cap);
        if (!items) return l->failed = true, SC_ENOMEM;
        l->items = items, l->cap = cap;
    }
    char *copy = sc_strdup(name);
    if (!copy) return l->failed = true, SC_ENOMEM;
    l->items[l->count++] = (sc_metric){copy, value};
    return SC_OK;
}

void sc_metric_list_free(sc_metric_list *l) {
    for (int32_t i = 0; i < l->count; i++) free(l->items[i].name);
    free(l->items);
    *l = (sc_metric_list){0};
}

int sc_report_metric(sc_report *r, const char *name, double value) {
    sc_metric *m = realloc(r->metrics, sizeof *m * (size_t)(r->nmetrics + 1));
    if (!m) return SC_ENOMEM;
    r->metrics = m;
    m[r->nmetrics].name = sc_strdup(name);
    m[r->nmetrics].value = value;
    if (!m[r->nmetrics].name) return SC_ENOMEM;
    r->nmetrics++;
    return SC_OK;
}

int sc_report_add_file(sc_report *r, const char *path, void *data, size_t size) {
    sc_value *bytes = sc_value_new_bytes(data, size);
    if (!bytes) return SC_ENOMEM;
    sc_report_file *f = realloc(r->files, sizeof *f * (size_t)(r->nfiles + 1));
    if (!f) {
        sc_value_release(bytes);
        return SC_ENOMEM;
    }
    r->files = f;
    f[r->nfiles].path = sc_strdup(path);
    f[r->nfiles].bytes = bytes;
    if (!f[r->nfiles].path) {
        sc_value_release(bytes);
        return SC_ENOMEM;
    }
    r->nfiles++;
    return SC_OK;
}

int sc_report_copy_files(sc_report *r, const char *from, const char *to) {
    size_t n = strlen(from);
    int32_t count = r->nfiles;
    for (int32_t i = 0; i < count; i++) {
        if (strncmp(r->files[i].path, from, n) != 0) continue;
        sc_report_file *f = realloc(r->files, sizeof *f * (size_t)(r->nfiles + 1));
        if (!f) return SC_ENOMEM;
        r->files = f;
        char *path = sc_strprintf("%s%s", to, f[i].path + n);
        if (!path) return SC_ENOMEM;
        f[r->nfiles].path = path;
        f[r->nfiles].bytes = sc_value_retain(f[i].bytes);
        r->nfiles++;
    }
    return SC_OK;
}

void sc_report_free(sc_report *r) {
    if (!r) return;
    for (int32_t i = 0; i < r->nmetrics; i++) free(r->metrics[i].name);
    for (int32_t i = 0; i < r->nfiles; i++) {
        free(r->files[i].path);
        sc_value_release(r->files[i].bytes);
    }
    free(r->metrics);
    free(r->files);
    free(r);
}

/* ---------------------------------------------------------------- encoding */

/* Where canonical bytes go: into a buffer, into a hasher, or both. */
typedef struct sink {
    sc_buf *buf;
    sc_hasher *hasher;
} sink;

static void put(sink *s, const void *p, size_t n) {
    if (s->buf) sc_buf_append(s->buf, p, n);
    if (s->hasher) sc_hasher_update(s->hasher, p, n);
}

static void put_u8(sink *s, uint8_t v) { put(s, &v, 1); }
static void put_u32(sink *s, uint32_t v) { put(s, &v, 4); }
static void put_u64(sink *s, uint64_t v) { put(s, &v, 8); }
static void put_f64(sink *s, double v) { put(s, &v, 8); }

static void put_str(sink *s, const char *str) {
    size_t n = str ? strlen(str) : 0;
    put_u32(s, (uint32_t)n);
    put(s, str, n);
}

static void put_digest(sink *s, const sc_value *v) { put(s, sc_value_digest(v)->bytes, 32); }

static void encode(const sc_value *v, sink *s) {
    put(s, "SCV", 3);
    put_u8(s, (uint8_t)v->kind);
    put_u32(s, SC_VALUE_FORMAT);
    switch (v->kind) {
    case SC_KIND_MESH: {
        const sc_mesh *m = v->as.mesh;
        put_u32(s, (uint32_t)m->nv), put_u32(s, (uint32_t)m->nu), put_u32(s, (uint32_t)m->nn);
        put_u32(s, (uint32_t)m->nf), put_u32(s, (uint32_t)m->nmat);
        for (int32_t i = 0; i < m->nmat; i++) put_str(s, m->materials[i]);
        put(s, m->V, sizeof(double) * 3 * (size_t)m->nv);
        put(s, m->U, sizeof(double) * 2 * (size_t)m->nu);
        if (m->nn) put(s, m->N, sizeof(double) * 3 * (size_t)m->nn);
        put(s, m->FV, sizeof(int32_t) * 3 * (size_t)m->nf);
        put(s, m->FU, sizeof(int32_t) * 3 * (size_t)m->nf);
        if (m->nn) put(s, m->FN, sizeof(int32_t) * 3 * (size_t)m->nf);
        put(s, m->FM, sizeof(int32_t) * (size_t)m->nf);
        break;
    }
    case SC_KIND_IMAGE: {
        const sc_image_data *im = v->as.image;
        put_u32(s, (uint32_t)im->width), put_u32(s, (uint32_t)im->height);
        put_u32(s, (uint32_t)im->channels), put_u8(s, (uint8_t)im->pixel);
        put_u8(s, (uint8_t)im->colorspace);
        char fmt[sizeof im->format + 1] = {0};
        memcpy(fmt, im->format, sizeof im->format);
        put_str(s, fmt);
        put(s, im->pixels, image_bytes(im));
        break;
    }
    case SC_KIND_ATLAS: {
        const sc_atlas *a = v->as.atlas;
        put_digest(s, a->mesh);
        put_u32(s, (uint32_t)a->ntex);
        for (int32_t i = 0; i < a->ntex; i++) {
            const sc_texture *t = &a->textures[i];
            put_str(s, t->name);
            put_u32(s, (uint32_t)t->material);
            put_u8(s, (uint8_t)t->wrap_u), put_u8(s, (uint8_t)t->wrap_v);
            put_str(s, t->source);
            put_digest(s, t->image);
        }
        put_u8(s, a->materials != NULL);
        for (int32_t i = 0; a->materials && i < a->mesh->as.mesh->nmat; i++) {
            const sc_material *m = &a->materials[i];
            for (int k = 0; k < 4; k++) put_f64(s, m->base_color[k]);
            put_f64(s, m->metallic), put_f64(s, m->roughness);
            for (int k = 0; k < 3; k++) put_f64(s, m->emissive[k]);
            put_f64(s, m->normal_scale), put_f64(s, m->occlusion_strength), put_f64(s, m->alpha_cutoff);
            put_u8(s, (uint8_t)m->alpha_mode), put_u8(s, m->double_sided);
        }
        break;
    }
    case SC_KIND_LODS: {
        const sc_lods *l = v->as.lods;
        put_u32(s, (uint32_t)l->count);
        for (int32_t i = 0; i < l->count; i++) put_digest(s, l->levels[i]);
        break;
    }
    case SC_KIND_REPORT: {
        const sc_report *r = v->as.report;
        put_u32(s, (uint32_t)r->nmetrics);
        for (int32_t i = 0; i < r->nmetrics; i++) {
            put_str(s, r->metrics[i].name);
            put_f64(s, r->metrics[i].value);
        }
        put_u32(s, (uint32_t)r->nfiles);
        for (int32_t i = 0; i < r->nfiles; i++) {
            put_str(s, r->files[i].path);
            put_digest(s, r->files[i].bytes);
        }
        break;
    }
    case SC_KIND_BYTES:
        put_u64(s, v->as.bytes->size);
        put(s, v->as.bytes->data, v->as.bytes->size);
        break;
    case SC_KIND_NONE:
        break;
    }
}

int sc_value_serialize(const sc_value *v, sc_buf *out) {
    sink s = {out, NULL};
    encode(v, &s);
    return out->failed ? SC_ENOMEM : SC_OK;
}

/* ---------------------------------------------------------------- values */

enum { DIGEST_PENDING, DIGEST_COMPUTING, DIGEST_KNOWN };

/* The value around payload; its hasher is made now, so that computing the
 * digest later cannot fail. */
static sc_value *seal(sc_kind kind, void *payload) {
    sc_value *v = calloc(1, sizeof *v);
    if (!v) return NULL;
    v->kind = kind;
    v->refs = 1;
    v->as.mesh = payload;   /* all union members are pointers */
    v->digest_state = DIGEST_PENDING;
    v->hasher = sc_hasher_new();
    if (!v->hasher) {
        free(v);
        return NULL;
    }
    return v;
}

const sc_digest *sc_value_digest(const sc_value *cv) {
    sc_value *v = (sc_value *)cv;   /* the digest is computed once, the payload only read */
    if (__atomic_load_n(&v->digest_state, __ATOMIC_ACQUIRE) == DIGEST_KNOWN) return &v->known_digest;
    int pending = DIGEST_PENDING;
    if (__atomic_compare_exchange_n(&v->digest_state, &pending, DIGEST_COMPUTING, false, __ATOMIC_ACQ_REL,
                                    __ATOMIC_ACQUIRE)) {
        sink s = {NULL, v->hasher};
        encode(v, &s);   /* parts' digests first, through this function */
        sc_hasher_final(v->hasher, &v->known_digest);
        v->hasher = NULL;
        __atomic_store_n(&v->digest_state, DIGEST_KNOWN, __ATOMIC_RELEASE);
    } else {
        while (__atomic_load_n(&v->digest_state, __ATOMIC_ACQUIRE) != DIGEST_KNOWN) sched_yield();
    }
    return &v->known_digest;
}

static void free_payload(sc_kind kind, void *payload) {
    switch (kind) {
    case SC_KIND_MESH: sc_mesh_free(payload); break;
    case SC_KIND_IMAGE: sc_image_free(payload); break;
    case SC_KIND_ATLAS: sc_atlas_free(payload); break;
    case SC_KIND_LODS: sc_lods_free(payload); break;
    case SC_KIND_REPORT: sc_report_free(payload); break;
    case SC_KIND_BYTES:
        if (payload) free(((sc_bytes *)payload)->data);
        free(payload);
        break;
    case SC_KIND_NONE: break;
    }
}

static sc_value *make(sc_kind kind, void *payload) {
    if (!payload) return NULL;
    sc_value *v = seal(kind, payload);
    if (!v) free_payload(kind, payload);
    return v;
}

sc_value *sc_value_new_mesh(sc_mesh *m) { return make(SC_KIND_MESH, m); }
sc_value *sc_value_new_image(sc_image_data *im) { return make(SC_KIND_IMAGE, im); }
sc_value *sc_value_new_atlas(sc_atlas *a) { return make(SC_KIND_ATLAS, a); }
sc_value *sc_value_new_lods(sc_lods *l) { return make(SC_KIND_LODS, l); }
sc_value *sc_value_new_report(sc_report *r) { return make(SC_KIND_REPORT, r); }

sc_value *sc_value_new_bytes(void *data, size_t size) {
    sc_bytes *b = malloc(sizeof *b);
    if (!b) {
        free(data);
        return NULL;
    }
    b->data = data;
    b->size = size;
    return make(SC_KIND_BYTES, b);
}

sc_value *sc_value_retain(sc_value *v) {
    if (v) __atomic_fetch_add(&v->refs, 1, __ATOMIC_RELAXED);
    return v;
}

void sc_value_release(sc_value *v) {
    if (!v) return;
    if (__atomic_fetch_sub(&v->refs, 1, __ATOMIC_ACQ_REL) != 1) return;
    if (v->hasher) {   /* never asked for its digest */
        sc_digest unused;
        sc_hasher_final(v->hasher, &unused);
    }
    free_payload(v->kind, v->as.mesh);
    free(v);
}

void sc_value_parts(const sc_value *v, void (*visit)(void *ud, sc_value *part), void *ud) {
    switch (v->kind) {
    case SC_KIND_ATLAS:
        visit(ud, v->as.atlas->mesh);
        for (int32_t i = 0; i < v->as.atlas->ntex; i++) visit(ud, v->as.atlas->textures[i].image);
        break;
    case SC_KIND_LODS:
        for (int32_t i = 0; i < v->as.lods->count; i++) visit(ud, v->as.lods->levels[i]);
        break;
    case SC_KIND_REPORT:
        for (int32_t i = 0; i < v->as.report->nfiles; i++) visit(ud, v->as.report->files[i].bytes);
        break;
    default:
        break;
    }
}

/* ---------------------------------------------------------------- decoding */

typedef struct decoder {
    sc_reader r;
    sc_value_resolver resolve;
    void *ud;
    sc_error *err;
    int failed;   /* an error already filled */
} decoder;

static int32_t get_count(decoder *d, uint32_t limit) {
    uint32_t n = sc_read_u32(&d->r);
    if (n > limit) d->r.failed = true;
    return (int32_t)n;
}

static bool get_array(decoder *d, void *dst, size_t bytes) {
    const void *p = sc_read_bytes(&d->r, bytes);
    if (!p) return false;
    if (bytes) memcpy(dst, p, bytes);
    return true;
}

/* Resolve a part named by digest, checking its kind. */
static sc_value *get_part(decoder *d, sc_kind kind) {
    const uint8_t *p = sc_read_bytes(&d->r, 32);
    if (!p || d->failed) return NULL;
    sc_digest dg;
    memcpy(dg.bytes, p, 32);
    sc_value *part = d->resolve ? d->resolve(d->ud, &dg, d->err) : NULL;
    if (!part) {
        if (!d->resolve) sc_fail(d->err, SC_EMISS, "no resolver for a part");
        d->failed = 1;
        return NULL;
    }
    if (part->kind != kind) {
        sc_value_release(part);
        sc_fail(d->err, SC_EINPUT, "part has kind %s, expected %s", sc_kind_name(part->kind),
                sc_kind_name(kind));
        d->failed = 1;
        return NULL;
    }
    return part;
}

static sc_mesh *decode_mesh(decoder *d) {
    int32_t nv = get_count(d, INT32_MAX / 3), nu = get_count(d, INT32_MAX / 3);
    int32_t nn = get_count(d, INT32_MAX / 3), nf = get_count(d, INT32_MAX / 3);
    int32_t nmat = get_count(d, 1u << 20);
    /* every count must be backed by bytes that are really there */
    size_t need = (size_t)nv * 24 + (size_t)nu * 16 + (size_t)nn * 24 + (size_t)nf * 28;
    if (d->r.failed || nmat < 1 || need > (size_t)(d->r.end - d->r.p)) return NULL;
    sc_mesh *m = sc_mesh_alloc(nv, nu, nn, nf, nmat);
    if (!m) return NULL;
    for (int32_t i = 0; i < nmat; i++) m->materials[i] = sc_read_str(&d->r);
    bool ok = get_array(d, m->V, sizeof(double) * 3 * (size_t)nv) &&
              get_array(d, m->U, sizeof(double) * 2 * (size_t)nu) &&
              (!nn || get_array(d, m->N, sizeof(double) * 3 * (size_t)nn)) &&
              get_array(d, m->FV, sizeof(int32_t) * 3 * (size_t)nf) &&
              get_array(d, m->FU, sizeof(int32_t) * 3 * (size_t)nf) &&
              (!nn || get_array(d, m->FN, sizeof(int32_t) * 3 * (size_t)nf)) &&
              get_array(d, m->FM, sizeof(int32_t) * (size_t)nf);
    if (!ok || d->r.failed || sc_mesh_check(m, NULL) != SC_OK) {
        sc_mesh_free(m);
        return NULL;
    }
    return m;
}

static sc_image_data *decode_image(decoder *d) {
    int32_t w = get_count(d, SC_IMAGE_MAX_SIDE), h = get_count(d, SC_IMAGE_MAX_SIDE);
    int32_t c = get_count(d, 4);
    sc_pixel pixel = (sc_pixel)sc_read_u8(&d->r);
    uint8_t cs = sc_read_u8(&d->r);
    char *fmt = sc_read_str(&d->r);
    if (d->r.failed || !fmt || cs > SC_COLOR_DATA) {
        free(fmt);
        return NULL;
    }
    sc_image_data *im = sc_image_alloc(w, h, c, pixel);
    if (!im) {
        free(fmt);
        return NULL;
    }
    im->colorspace = (sc_colorspace)cs;
    snprintf(im->format, sizeof im->format, "%s", fmt);
    free(fmt);
    if (!get_array(d, im->pixels, image_bytes(im))) {
        sc_image_free(im);
        return NULL;
    }
    return im;
}

static sc_atlas *decode_atlas(decoder *d) {
    sc_value *mesh = get_part(d, SC_KIND_MESH);
    if (!mesh) return NULL;
    sc_atlas *a = sc_atlas_new(mesh);
    if (!a) return NULL;
    int32_t ntex = get_count(d, 1u << 16);
    for (int32_t i = 0; i < ntex && !d->r.failed && !d->failed; i++) {
        char *name = sc_read_str(&d->r);
        int32_t material = (int32_t)sc_read_u32(&d->r);
        uint8_t wu = sc_read_u8(&d->r), wv = sc_read_u8(&d->r);
        char *source = sc_read_str(&d->r);
        sc_value *image = (name && source && !d->r.failed) ? get_part(d, SC_KIND_IMAGE) : NULL;
        if (image && (wu > SC_WRAP_MIRROR || wv > SC_WRAP_MIRROR || material < 0 ||
                      material >= mesh->as.mesh->nmat)) {
            sc_value_release(image);
            image = NULL;
            d->r.failed = true;
        }
        if (image && sc_atlas_add_texture(a, name, material, (sc_wrap)wu, (sc_wrap)wv, source,
                                          image) != SC_OK)
            d->r.failed = true;
        free(name);
        free(source);
        if (!image) d->r.failed = true;
    }
    int32_t nmat = mesh->as.mesh->nmat;
    if (!d->r.failed && !d->failed && sc_read_u8(&d->r)) {
        a->materials = malloc((size_t)(nmat > 0 ? nmat : 1) * sizeof *a->materials);
        if (!a->materials) d->failed = true;
        for (int32_t i = 0; a->materials && i < nmat && !d->r.failed; i++) {
            sc_material *m = &a->materials[i];
            for (int k = 0; k < 4; k++) m->base_color[k] = sc_read_f64(&d->r);
            m->metallic = sc_read_f64(&d->r), m->roughness = sc_read_f64(&d->r);
            for (int k = 0; k < 3; k++) m->emissive[k] = sc_read_f64(&d->r);
            m->normal_scale = sc_read_f64(&d->r), m->occlusion_strength = sc_read_f64(&d->r);
            m->alpha_cutoff = sc_read_f64(&d->r);
            uint8_t mode = sc_read_u8(&d->r), sided = sc_read_u8(&d->r);
            if (mode > SC_ALPHA_BLEND || sided > 1) d->r.failed = true;
            m->alpha_mode = (sc_alpha_mode)mode, m->double_sided = sided;
        }
    }
    if (d->r.failed || d->failed) {
        sc_atlas_free(a);
        return NULL;
    }
    return a;
}

static sc_lods *decode_lods(decoder *d) {
    sc_lods *l = sc_lods_new();
    int32_t n = get_count(d, 1u << 16);
    for (int32_t i = 0; l && i < n && !d->r.failed && !d->failed; i++) {
        sc_value *a = get_part(d, SC_KIND_ATLAS);
        if (!a || sc_lods_add(l, a) != SC_OK) d->r.failed = true;
    }
    if (!l || d->r.failed || d->failed) {
        sc_lods_free(l);
        return NULL;
    }
    return l;
}

static sc_report *decode_report(decoder *d) {
    sc_report *r = sc_report_new();
    if (!r) return NULL;
    int32_t nm = get_count(d, 1u << 20);
    for (int32_t i = 0; i < nm && !d->r.failed; i++) {
        char *name = sc_read_str(&d->r);
        double value = sc_read_f64(&d->r);
        if (!name || sc_report_metric(r, name, value) != SC_OK) d->r.failed = true;
        free(name);
    }
    int32_t nfiles = get_count(d, 1u << 20);
    for (int32_t i = 0; i < nfiles && !d->r.failed && !d->failed; i++) {
        char *path = sc_read_str(&d->r);
        sc_value *bytes = path ? get_part(d, SC_KIND_BYTES) : NULL;
        sc_report_file *f = bytes ? realloc(r->files, sizeof *f * (size_t)(r->nfiles + 1)) : NULL;
        if (!f) {
            free(path);
            sc_value_release(bytes);
            d->r.failed = true;
            break;
        }
        r->files = f;
        f[r->nfiles].path = path;
        f[r->nfiles].bytes = bytes;
        r->nfiles++;
    }
    if (d->r.failed || d->failed) {
        sc_report_free(r);
        return NULL;
    }
    return r;
}

sc_value *sc_value_deserialize(const void *bytes, size_t n, const sc_digest *expect,
                               sc_value_resolver resolve, void *ud, sc_error *err) {
    decoder d = {.resolve = resolve, .ud = ud, .err = err};
    sc_reader_init(&d.r, bytes, n);
    const char *magic = sc_read_bytes(&d.r, 3);
    sc_kind kind = (sc_kind)sc_read_u8(&d.r);
    uint32_t format = sc_read_u32(&d.r);
    if (!magic || memcmp(magic, "SCV", 3) != 0 || format != SC_VALUE_FORMAT) {
        sc_fail(err, SC_EINPUT, "not a seamcook value of format %d", SC_VALUE_FORMAT);
        return NULL;
    }
    void *payload = NULL;
    switch (kind) {
    case SC_KIND_MESH: payload = decode_mesh(&d); break;
    case SC_KIND_IMAGE: payload = decode_image(&d); break;
    case SC_KIND_ATLAS: payload = decode_atlas(&d); break;
    case SC_KIND_LODS: payload = decode_lods(&d); break;
    case SC_KIND_REPORT: payload = decode_report(&d); break;
    case SC_KIND_BYTES: {
        uint64_t size = sc_read_u64(&d.r);
        const void *p = size <= (uint64_t)(d.r.end - d.r.p) ? sc_read_bytes(&d.r, (size_t)size) : NULL;
        void *copy = p ? malloc(size ? (size_t)size : 1) : NULL;
        if (copy) {
            memcpy(copy, p, (size_t)size);
            sc_bytes *b = malloc(sizeof *b);
            if (b) {
                b->data = copy, b->size = (size_t)size;
                payload = b;
            } else {
                free(copy);
            }
        }
        break;
    }
    case SC_KIND_NONE:
        break;
    }
    if (!payload || d.r.p != d.r.end) {
        free_payload(kind, payload);
        if (!d.failed) sc_fail(err, SC_EINPUT, "malformed %s value", sc_kind_name(kind));
        return NULL;
    }
    sc_value *v = make(kind, payload);
    if (!v) {
        sc_fail(err, SC_ENOMEM, "out of memory");
        return NULL;
    }
    if (expect && !sc_digest_equal(sc_value_digest(v), expect)) {
        sc_value_release(v);
        sc_fail(err, SC_EMISS, "value does not match its digest");
        return NULL;
    }
    return v;
}

typedef struct quantize_job {
    const sc_image_data *f;
    sc_image_data *q;
    bool encode;   /* linear colour through the transfer curve */
    double maxv;
} quantize_job;

#define QUANTIZE_ROWS 64

static int quantize_rows(void *ud, int32_t chunk) {
    const quantize_job *j = ud;
    const sc_image_data *f = j->f;
    const int32_t C = f->channels;
    const int32_t y0 = chunk * QUANTIZE_ROWS, y1 = y0 + QUANTIZE_ROWS < f->height ? y0 + QUANTIZE_ROWS : f->height;
    const size_t k0 = (size_t)y0 * f->width * C, k1 = (size_t)y1 * f->width * C;
    const float *px = f->pixels;
    for (size_t k = k0; k < k1; k++) {
        float x = j->encode && !sc_channel_is_alpha(C, (int32_t)(k % (size_t)C)) ? sc_linear_to_srgb(px[k]) : px[k];
        long v = lrint((x > 0 ? (x < 1 ? x : 1) : 0) * j->maxv);
        if (j->q->pixel == SC_PIXEL_U8) ((uint8_t *)j->q->pixels)[k] = (uint8_t)v;
        else ((uint16_t *)j->q->pixels)[k] = (uint16_t)v;
    }
    return SC_OK;
}

sc_image_data *sc_image_quantize(const sc_image_data *f, sc_pixel pixel, sc_colorspace space) {
    return sc_image_quantize_threads(f, pixel, space, 1);
}

sc_image_data *sc_image_quantize_threads(const sc_image_data *f, sc_pixel pixel, sc_colorspace space, int threads) {
    sc_image_data *q = sc_image_alloc(f->width, f->height, f->channels, pixel);
    if (!q) return NULL;
    q->colorspace = space;
    memcpy(q->format, f->format, sizeof q->format);
    quantize_job j = {f, q, f->colorspace == SC_COLOR_LINEAR && space == SC_COLOR_SRGB,
                      pixel == SC_PIXEL_U8 ? 255.0 : 65535.0};
    int32_t chunks = (f->height + QUANTIZE_ROWS - 1) / QUANTIZE_ROWS;
    if (sc_parallel(threads, chunks, quantize_rows, &j) != SC_OK)
        for (int32_t c = 0; c < chunks; c++) quantize_rows(&j, c);
    return q;
}
