/* sc_gltf.c - glTF 2.0 reader (see sc_gltf.h for what it accepts).
 *
 * Design note: cJSON parses the JSON (from a .gltf, or a .glb's JSON chunk);
 * the top-level arrays are indexed once into pointer vectors so that every
 * cross-reference is an O(1), bounds-checked lookup. Buffers load lazily, the
 * first time an accessor or image needs them, so unused buffers are never
 * read. Every number taken from the file goes through one of three checked
 * getters (integer in a range, reference into a list, fixed-size array of
 * finite numbers), and every byte range is checked against the range that
 * contains it (accessor within bufferView within buffer) before a byte is
 * read, with 64-bit arithmetic on values already bounded by the checks.
 *
 * Geometry is gathered as raw vertices (transformed positions, flipped uvs,
 * transformed normals) and triangles over raw indices, exactly as the scene
 * lists them. Welding then maps raw vertices to distinct positions and to
 * distinct (position, uv) pairs with two hash tables keyed by the bits of the
 * canonical doubles (-0 folded into +0), numbered by first appearance, and
 * the OBJ reader's last step (sc_mesh_build_compact) drops degenerate
 * triangles and unused entries.
 */
#include "sc_gltf.h"
#include "sc_tangent.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cjson/cJSON.h>

#include "sc_obj.h"

static const sc_kernel *const gltf_uses[] = {&sc_kernel_obj, &sc_kernel_tangent, NULL};
const sc_kernel sc_kernel_gltf = {"gltf", SC_GLTF_VERSION, gltf_uses};

#define MAX_NODE_DEPTH 1000
#define MAX_NODE_VISITS (1 << 20)
#define MAX_JSON_INT 9007199254740992.0   /* 2^53 */
#define REQUIRED INT64_MIN

enum {
    CT_I8 = 5120, CT_U8 = 5121, CT_I16 = 5122, CT_U16 = 5123, CT_U32 = 5125, CT_F32 = 5126,
};

typedef struct list {
    const cJSON **items;
    int64_t count;
} list;

typedef struct buffer {
    bool loaded;
    const uint8_t *data;
    uint8_t *owned;
    size_t size;
} buffer;

typedef struct accessor {
    int64_t index;
    const uint8_t *data;
    size_t stride;
    int64_t count;
    int ncomp, ctype, csize;
    bool normalized;
} accessor;

typedef struct reader {
    const char *name;
    sc_error *err;
    sc_gltf_read_fn read;
    void *ud;
    cJSON *root;
    const uint8_t *glb_bin;
    size_t glb_bin_size;
    bool has_glb_bin;
    list accessors, views, buffers, nodes, meshes, materials, textures, images, samplers, scenes;
    buffer *bufs;
    bool *on_path;
    int64_t node_visits;

    /* raw geometry */
    double *P, *UV, *N;
    int64_t nraw, capP, capUV, capN;
    int32_t *tri, *tri_material;
    int64_t ntri, captri, captm;
    bool all_normals;
    bool quantized;             /* KHR_mesh_quantization used: integer positions, normals and uv */
    int64_t primitives_skipped;
    int64_t faces_without_uv;   /* triangles of primitives without TEXCOORD_0 */
    /* per glTF material (index + 1; 0: none): corners whose TANGENT's
     * bitangent runs with and against increasing v (GL uv) */
    int64_t *tangent_with, *tangent_against;
} reader;

/* ---------------------------------------------------------------- helpers */

static int fail(reader *r, int code, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
static int fail(reader *r, int code, const char *fmt, ...) {
    char text[900];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(text, sizeof text, fmt, ap);
    va_end(ap);
    return sc_fail(r->err, code, "%s: %s", r->name, text);
}

static bool grow_array(void **items, int64_t *cap, int64_t need, size_t elem) {
    if (need <= *cap) return true;
    int64_t c = *cap ? *cap : 1024;
    while (c < need) c *= 2;
    void *q = sc_realloc_array(*items, (size_t)c, elem);
    if (!q) return false;
    *items = q;
    *cap = c;
    return true;
}

static const cJSON *field(const cJSON *obj, const char *key) {
    return cJSON_IsObject(obj) ? cJSON_GetObjectItemCaseSensitive(obj, key) : NULL;
}

/* An integer field in [min, max]; absent gives def, or an error when def is
 * REQUIRED. */
static int get_int(reader *r, const char *ctx, const cJSON *obj, const char *key, int64_t def,
                   int64_t min, int64_t max, int64_t *out) {
    const cJSON *v = field(obj, key);
    if (!v) {
        if (def == REQUIRED) return fail(r, SC_EINPUT, "%s: '%s' is missing", ctx, key);
        *out = def;
        return SC_OK;
    }
    double d = cJSON_IsNumber(v) ? v->valuedouble : NAN;
    if (!(d == floor(d) && d >= (double)min && d <= (double)max))
        return fail(r, SC_EINPUT, "%s: '%s' must be an integer in [%lld, %lld]", ctx, key,
                    (long long)min, (long long)max);
    *out = (int64_t)d;
    return SC_OK;
}

/* A reference into a list: -1 when absent and optional. */
static int get_ref(reader *r, const char *ctx, const cJSON *obj, const char *key, const list *l,
                   const char *what, bool required, int64_t *out) {
    const cJSON *v = field(obj, key);
    if (!v) {
        if (required) return fail(r, SC_EINPUT, "%s: '%s' is missing", ctx, key);
        *out = -1;
        return SC_OK;
    }
    double d = cJSON_IsNumber(v) ? v->valuedouble : NAN;
    if (!(d == floor(d) && d >= 0 && d < (double)l->count)) {
        if (!cJSON_IsNumber(v)) return fail(r, SC_EINPUT, "%s: '%s' is not a %s index", ctx, key, what);
        return fail(r, SC_EINPUT, "%s: '%s' refers to %s %.0f, the file has %lld", ctx, key, what,
                    d, (long long)l->count);
    }
    *out = (int64_t)d;
    return SC_OK;
}

/* Fill n finite numbers from an array field; absent leaves out unchanged. */
static int get_numbers(reader *r, const char *ctx, const cJSON *obj, const char *key, int n,
                       double *out, bool *present) {
    const cJSON *v = field(obj, key);
    if (present) *present = v != NULL;
    if (!v) return SC_OK;
    if (!cJSON_IsArray(v) || cJSON_GetArraySize(v) != n)
        return fail(r, SC_EINPUT, "%s: '%s' must be an array of %d numbers", ctx, key, n);
    int i = 0;
    const cJSON *e;
    cJSON_ArrayForEach(e, v) {
        if (!cJSON_IsNumber(e) || !isfinite(e->valuedouble))
            return fail(r, SC_EINPUT, "%s: '%s'[%d] is not a finite number", ctx, key, i);
        out[i++] = e->valuedouble;
    }
    return SC_OK;
}

static int index_list(reader *r, const char *key, list *l) {
    const cJSON *a = field(r->root, key);
    l->items = NULL;
    l->count = 0;
    if (!a) return SC_OK;
    if (!cJSON_IsArray(a)) return fail(r, SC_EINPUT, "'%s' is not an array", key);
    int n = cJSON_GetArraySize(a);
    if (n == 0) return SC_OK;
    l->items = sc_alloc_array((size_t)n, sizeof *l->items);
    if (!l->items) return fail(r, SC_ENOMEM, "out of memory");
    const cJSON *e;
    cJSON_ArrayForEach(e, a) {
        if (!cJSON_IsObject(e))
            return fail(r, SC_EINPUT, "%s[%lld] is not an object", key, (long long)l->count);
        l->items[l->count++] = e;
    }
    return SC_OK;
}

/* One finite number field in [min, max]; absent leaves *out unchanged. */
static int get_number(reader *r, const char *ctx, const cJSON *obj, const char *key, double min, double max,
                      double *out) {
    const cJSON *v = field(obj, key);
    if (!v) return SC_OK;
    if (!cJSON_IsNumber(v) || !(v->valuedouble >= min && v->valuedouble <= max))
        return fail(r, SC_EINPUT, "%s: '%s' must be a number in [%g, %g]", ctx, key, min, max);
    *out = v->valuedouble;
    return SC_OK;
}

/* ---------------------------------------------------------------- URIs */

static int base64_value(unsigned char c) {
    if (c >= 'A' && c <= 'Z') return c - 'A';
    if (c >= 'a' && c <= 'z') return c - 'a' + 26;
    if (c >= '0' && c <= '9') return c - '0' + 52;
    if (c == '+' || c == '-') return 62;
    if (c == '/' || c == '_') return 63;
    return -1;
}

/* Decode a data: URI (base64 only) into a new array. */
static int decode_data_uri(reader *r, const char *ctx, const char *uri, uint8_t **out, size_t *size) {
    const char *comma = strchr(uri, ',');
    if (!comma || comma - uri < 12 || strncmp(comma - 7, ";base64", 7) != 0)
        return fail(r, SC_EINPUT, "%s: only base64 data: URIs are supported", ctx);
    const char *s = comma + 1;
    size_t n = strlen(s);
    while (n > 0 && s[n - 1] == '=') n--;
    uint8_t *data = malloc(n / 4 * 3 + 3);
    if (!data) return fail(r, SC_ENOMEM, "out of memory");
    size_t k = 0;
    uint32_t acc = 0;
    int bits = 0;
    for (size_t i = 0; i < n; i++) {
        int v = base64_value((unsigned char)s[i]);
        if (v < 0) {
            free(data);
            return fail(r, SC_EINPUT, "%s: data: URI has a byte that is not base64 at %zu", ctx, i);
        }
        acc = (acc << 6) | (uint32_t)v;
        bits += 6;
        if (bits >= 8) {
            bits -= 8;
            data[k++] = (uint8_t)(acc >> bits);
        }
    }
    *out = data;
    *size = k;
    return SC_OK;
}

static int hex_digit(char c) {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
}

/* A relative file URI as a path: %XX decoded; URLs with a scheme rejected. */
static int uri_to_path(reader *r, const char *ctx, const char *uri, char **out) {
    char shown[320];
    if (!*uri) return fail(r, SC_EINPUT, "%s: empty uri", ctx);
    const char *colon = strchr(uri, ':');
    const char *slash = strchr(uri, '/');
    if (colon && (!slash || colon < slash))
        return fail(r, SC_EINPUT, "%s: uri '%s' is not a relative file name", ctx,
                    sc_excerpt(uri, 60, false, shown, sizeof shown));
    char *path = malloc(strlen(uri) + 1);
    if (!path) return fail(r, SC_ENOMEM, "out of memory");
    size_t k = 0;
    for (const char *s = uri; *s; s++) {
        int hi, lo;
        if (*s == '%' && (hi = hex_digit(s[1])) >= 0 && (lo = hex_digit(s[2])) >= 0) {
            path[k++] = (char)(hi * 16 + lo);
            s += 2;
        } else {
            path[k++] = *s;
        }
    }
    path[k] = 0;
    if (k != strlen(path)) {
        free(path);
        return fail(r, SC_EINPUT, "%s: uri '%s' decodes to a NUL byte", ctx,
                    sc_excerpt(uri, 60, false, shown, sizeof shown));
    }
    *out = path;
    return SC_OK;
}

/* ---------------------------------------------------------------- buffers, views, accessors */

static int load_buffer(reader *r, int64_t i, const uint8_t **data, size_t *size) {
    buffer *b = &r->bufs[i];
    if (!b->loaded) {
        char ctx[64];
        snprintf(ctx, sizeof ctx, "buffer %lld", (long long)i);
        const cJSON *obj = r->buffers.items[i];
        int64_t length = 0;
        int rc = get_int(r, ctx, obj, "byteLength", REQUIRED, 1, (int64_t)MAX_JSON_INT, &length);
        if (rc) return rc;
        const cJSON *uri = field(obj, "uri");
        size_t got = 0;
        if (uri) {
            if (!cJSON_IsString(uri)) return fail(r, SC_EINPUT, "%s: 'uri' is not a string", ctx);
            if (strncmp(uri->valuestring, "data:", 5) == 0) {
                if ((rc = decode_data_uri(r, ctx, uri->valuestring, &b->owned, &got))) return rc;
            } else {
                char *path = NULL;
                if ((rc = uri_to_path(r, ctx, uri->valuestring, &path))) return rc;
                sc_buf bytes;
                sc_buf_init(&bytes);
                rc = r->read ? r->read(r->ud, path, &bytes, r->err)
                             : sc_fail(r->err, SC_EINPUT, "no reader for external files");
                if (rc != SC_OK) {
                    if (r->err && !r->err->message[0]) sc_fail(r->err, rc, "cannot read it");
                    sc_error_prefix(r->err, "%s: %s (%s)", r->name, ctx, path);
                    free(path);
                    sc_buf_free(&bytes);
                    return rc;
                }
                free(path);
                b->owned = bytes.data;
                got = bytes.len;
            }
            b->data = b->owned;
        } else if (r->has_glb_bin && i == 0) {
            b->data = r->glb_bin;
            got = r->glb_bin_size;
        } else {
            return fail(r, SC_EINPUT, "%s has no uri and the file has no binary chunk", ctx);
        }
        if ((uint64_t)length > got)
            return fail(r, SC_EINPUT, "%s: byteLength is %lld but only %zu bytes are there", ctx,
                        (long long)length, got);
        b->size = (size_t)length;
        b->loaded = true;
    }
    *data = b->data;
    *size = b->size;
    return SC_OK;
}

/* The bytes of a bufferView, checked against its buffer. */
static int open_view(reader *r, const char *who, int64_t v, const uint8_t **data, size_t *len,
                     size_t *stride) {
    char ctx[128];
    snprintf(ctx, sizeof ctx, "%s: bufferView %lld", who, (long long)v);
    const cJSON *obj = r->views.items[v];
    int64_t buf = 0, offset = 0, length = 0, byte_stride = 0;
    int rc;
    if ((rc = get_ref(r, ctx, obj, "buffer", &r->buffers, "buffer", true, &buf)) ||
        (rc = get_int(r, ctx, obj, "byteOffset", 0, 0, (int64_t)MAX_JSON_INT, &offset)) ||
        (rc = get_int(r, ctx, obj, "byteLength", REQUIRED, 1, (int64_t)MAX_JSON_INT, &length)) ||
        (rc = get_int(r, ctx, obj, "byteStride", 0, 0, 252, &byte_stride)))
        return rc;
    const uint8_t *bytes = NULL;
    size_t size = 0;
    if ((rc = load_buffer(r, buf, &bytes, &size))) return rc;
    if ((uint64_t)offset > size || (uint64_t)length > size - (uint64_t)offset)
        return fail(r, SC_EINPUT, "%s: bytes %lld to %lld are past the end of buffer %lld (%zu bytes)",
                    ctx, (long long)offset, (long long)(offset + length), (long long)buf, size);
    *data = bytes + offset;
    *len = (size_t)length;
    if (stride) *stride = (size_t)byte_stride;
    return SC_OK;
}

static int component_size(int ctype) {
    switch (ctype) {
    case CT_I8: case CT_U8: return 1;
    case CT_I16: case CT_U16: return 2;
    case CT_U32: case CT_F32: return 4;
    }
    return 0;
}

static int type_components(const char *type) {
    static const struct { const char *name; int n; } types[] = {
        {"SCALAR", 1}, {"VEC2", 2}, {"VEC3", 3}, {"VEC4", 4}, {"MAT2", 4}, {"MAT3", 9}, {"MAT4", 16},
    };
    for (size_t i = 0; i < sizeof types / sizeof types[0]; i++)
        if (strcmp(type, types[i].name) == 0) return types[i].n;
    return 0;
}

static int open_accessor(reader *r, int64_t a, int want_components, const char *role, accessor *out) {
    char ctx[64];
    snprintf(ctx, sizeof ctx, "accessor %lld", (long long)a);
    const cJSON *obj = r->accessors.items[a];
    memset(out, 0, sizeof *out);
    out->index = a;
    if (field(obj, "sparse"))
        return fail(r, SC_EINPUT, "%s: sparse accessors are not supported", ctx);
    int64_t ctype = 0, count = 0, view = -1, offset = 0;
    int rc;
    if ((rc = get_int(r, ctx, obj, "componentType", REQUIRED, 0, 1 << 20, &ctype))) return rc;
    if (!component_size((int)ctype))
        return fail(r, SC_EINPUT, "%s: componentType %lld is not a glTF component type", ctx, (long long)ctype);
    const cJSON *type = field(obj, "type");
    int ncomp = cJSON_IsString(type) ? type_components(type->valuestring) : 0;
    if (!ncomp) return fail(r, SC_EINPUT, "%s: 'type' is missing or unknown", ctx);
    if (ncomp != want_components)
        return fail(r, SC_EINPUT, "%s: %s must have %d component%s, has type %s", ctx, role,
                    want_components, want_components == 1 ? "" : "s", type->valuestring);
    if ((rc = get_int(r, ctx, obj, "count", REQUIRED, 1, SC_GLTF_MAX_ELEMENTS, &count)) ||
        (rc = get_ref(r, ctx, obj, "bufferView", &r->views, "bufferView", false, &view)) ||
        (rc = get_int(r, ctx, obj, "byteOffset", 0, 0, (int64_t)MAX_JSON_INT, &offset)))
        return rc;
    const cJSON *normalized = field(obj, "normalized");
    out->normalized = cJSON_IsTrue(normalized);
    out->ctype = (int)ctype;
    out->csize = component_size((int)ctype);
    out->ncomp = ncomp;
    out->count = count;
    /* Without a bufferView an accessor is all zeros, which only makes sense
     * with sparse values (rejected above); refusing it also means every
     * element the reader allocates is backed by bytes of the file. */
    if (view < 0) return fail(r, SC_EINPUT, "%s: has no bufferView (all-zero accessors are not supported)", ctx);
    const uint8_t *bytes = NULL;
    size_t len = 0, stride = 0;
    if ((rc = open_view(r, ctx, view, &bytes, &len, &stride))) return rc;
    size_t elem = (size_t)out->csize * (size_t)ncomp;
    if (stride == 0) stride = elem;
    if (stride < elem)
        return fail(r, SC_EINPUT, "%s: bufferView %lld has byteStride %zu, smaller than an element (%zu bytes)",
                    ctx, (long long)view, stride, elem);
    /* count <= 2^26 and stride <= 252: no overflow */
    uint64_t need = (uint64_t)offset + (uint64_t)(count - 1) * stride + elem;
    if ((uint64_t)offset > len || need > len)
        return fail(r, SC_EINPUT,
                    "%s: count %lld with stride %zu from offset %lld needs %llu bytes, bufferView %lld has %zu",
                    ctx, (long long)count, stride, (long long)offset, (unsigned long long)need,
                    (long long)view, len);
    out->data = bytes + offset;
    out->stride = stride;
    return SC_OK;
}

static double accessor_get(const accessor *a, int64_t i, int c) {
    const uint8_t *p = a->data + (size_t)i * a->stride + (size_t)c * (size_t)a->csize;
    switch (a->ctype) {
    case CT_F32: {
        float f;
        memcpy(&f, p, 4);
        return f;
    }
    case CT_U8: return a->normalized ? p[0] / 255.0 : p[0];
    case CT_I8: {
        int8_t v = (int8_t)p[0];
        return a->normalized ? fmax(v / 127.0, -1.0) : v;
    }
    case CT_U16: {
        uint16_t v;
        memcpy(&v, p, 2);
        return a->normalized ? v / 65535.0 : v;
    }
    case CT_I16: {
        int16_t v;
        memcpy(&v, p, 2);
        return a->normalized ? fmax(v / 32767.0, -1.0) : v;
    }
    case CT_U32: {
        uint32_t v;
        memcpy(&v, p, 4);
        return v;
    }
    }
    return 0;
}

/* ---------------------------------------------------------------- geometry */

typedef double mat4[4][4];   /* row-major: m[row][col] */

static void mat4_identity(mat4 m) {
    memset(m, 0, sizeof(mat4));
    for (int i = 0; i < 4; i++) m[i][i] = 1;
}

static void mat4_mul(const mat4 a, const mat4 b, mat4 out) {
    mat4 c;
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++) {
            double s = 0;
            for (int k = 0; k < 4; k++) s += a[i][k] * b[k][j];
            c[i][j] = s;
        }
    memcpy(out, c, sizeof c);
}

/* The node's local matrix: `matrix` (column-major) or T * R * S. */
static int node_matrix(reader *r, const char *ctx, const cJSON *node, mat4 out) {
    double a[16];
    bool has_matrix = false;
    int rc = get_numbers(r, ctx, node, "matrix", 16, a, &has_matrix);
    if (rc) return rc;
    if (has_matrix) {
        for (int row = 0; row < 4; row++)
            for (int col = 0; col < 4; col++) out[row][col] = a[col * 4 + row];
        return SC_OK;
    }
    double t[3] = {0, 0, 0}, q[4] = {0, 0, 0, 1}, s[3] = {1, 1, 1};
    if ((rc = get_numbers(r, ctx, node, "translation", 3, t, NULL)) ||
        (rc = get_numbers(r, ctx, node, "rotation", 4, q, NULL)) ||
        (rc = get_numbers(r, ctx, node, "scale", 3, s, NULL)))
        return rc;
    mat4 T, R, S;
    mat4_identity(T), mat4_identity(R), mat4_identity(S);
    for (int i = 0; i < 3; i++) T[i][3] = t[i], S[i][i] = s[i];
    double x = q[0], y = q[1], z = q[2], w = q[3];
    R[0][0] = 1 - 2 * (y * y + z * z), R[0][1] = 2 * (x * y - z * w), R[0][2] = 2 * (x * z + y * w);
    R[1][0] = 2 * (x * y + z * w), R[1][1] = 1 - 2 * (x * x + z * z), R[1][2] = 2 * (y * z - x * w);
    R[2][0] = 2 * (x * z - y * w), R[2][1] = 2 * (y * z + x * w), R[2][2] = 1 - 2 * (x * x + y * y);
    mat4 TR;
    mat4_mul(T, R, TR);
    mat4_mul(TR, S, out);
    return SC_OK;
}

/* The normal matrix: the inverse transpose of the upper 3x3, up to a positive
 * scale (the cofactor matrix times the sign of the determinant), so that it
 * exists even for singular matrices; normals are renormalised anyway. */
static void normal_matrix(const mat4 m, double n[3][3]) {
    double c[3][3];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            int i1 = (i + 1) % 3, i2 = (i + 2) % 3, j1 = (j + 1) % 3, j2 = (j + 2) % 3;
            c[i][j] = m[i1][j1] * m[i2][j2] - m[i1][j2] * m[i2][j1];
        }
    double det = m[0][0] * c[0][0] + m[0][1] * c[0][1] + m[0][2] * c[0][2];
    double sign = det < 0 ? -1 : 1;
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) n[i][j] = sign * c[i][j];
}

/* ---------------------------------------------------------------- texture transforms */

/* KHR_texture_transform as an affine map of glTF uv (top-left origin):
 * u' = m[0] u + m[1] v + m[2], v' = m[3] u + m[4] v + m[5], the extension's
 * translation x rotation x scale: u' = sx u cos r + sy v sin r + ox,
 * v' = sy v cos r - sx u sin r + oy. */
typedef struct uv_transform {
    double m[6];
} uv_transform;

static const uv_transform uv_identity = {{1, 0, 0, 0, 1, 0}};

/* A textureInfo's transform (identity when it has none) and the uv set it
 * samples (the extension's texCoord overrides the textureInfo's). */
static int texture_transform(reader *r, const char *ctx, const char *slot, const cJSON *info, uv_transform *out,
                             int64_t *texcoord) {
    char tctx[96];
    snprintf(tctx, sizeof tctx, "%s: the %s texture", ctx, slot);
    int rc = get_int(r, tctx, info, "texCoord", 0, 0, 1 << 20, texcoord);
    const cJSON *x = field(field(info, "extensions"), "KHR_texture_transform");
    *out = uv_identity;
    if (rc || !x) return rc;
    snprintf(tctx, sizeof tctx, "%s: the %s texture's KHR_texture_transform", ctx, slot);
    if (!cJSON_IsObject(x)) return fail(r, SC_EINPUT, "%s is not an object", tctx);
    double offset[2] = {0, 0}, scale[2] = {1, 1}, rotation = 0;
    const cJSON *rot = field(x, "rotation");
    if (rot && !(cJSON_IsNumber(rot) && isfinite(rot->valuedouble)))
        return fail(r, SC_EINPUT, "%s: 'rotation' is not a finite number", tctx);
    if (rot) rotation = rot->valuedouble;
    if ((rc = get_numbers(r, tctx, x, "offset", 2, offset, NULL)) ||
        (rc = get_numbers(r, tctx, x, "scale", 2, scale, NULL)) ||
        (rc = get_int(r, tctx, x, "texCoord", *texcoord, 0, 1 << 20, texcoord)))
        return rc;
    double c = cos(rotation), s = sin(rotation);
    *out = (uv_transform){{scale[0] * c, scale[1] * s, offset[0], -scale[0] * s, scale[1] * c, offset[1]}};
    return SC_OK;
}

/* The one transform every texture of material gm that samples TEXCOORD_0
 * applies: the uv are transformed as they are read, so the atlas holds the
 * uv each texture is really sampled at. Textures of one material that
 * transform TEXCOORD_0 differently would need uv sets of their own: an
 * error naming them. */
static int material_transform(reader *r, int64_t gm, uv_transform *out) {
    *out = uv_identity;
    if (gm < 0) return SC_OK;
    char ctx[64];
    snprintf(ctx, sizeof ctx, "material %lld", (long long)gm);
    const cJSON *m = r->materials.items[gm], *pbr = field(m, "pbrMetallicRoughness");
    const cJSON *color = field(pbr, "baseColorTexture");
    if (!color)
        color = field(field(field(m, "extensions"), "KHR_materials_pbrSpecularGlossiness"), "diffuseTexture");
    const struct {
        const char *slot;
        const cJSON *info;
    } slots[] = {{"color", color},
                 {"normal", field(m, "normalTexture")},
                 {"emissive", field(m, "emissiveTexture")},
                 {"occlusion", field(m, "occlusionTexture")},
                 {"metallic_roughness", field(pbr, "metallicRoughnessTexture")}};
    const char *first = NULL;
    for (size_t i = 0; i < sizeof slots / sizeof slots[0]; i++) {
        if (!cJSON_IsObject(slots[i].info)) continue;
        uv_transform t;
        int64_t texcoord = 0;
        int rc = texture_transform(r, ctx, slots[i].slot, slots[i].info, &t, &texcoord);
        if (rc) return rc;
        if (texcoord != 0) continue;
        if (!first) {
            *out = t, first = slots[i].slot;
        } else if (memcmp(out->m, t.m, sizeof t.m) != 0) {
            return fail(r, SC_EINPUT, "%s: the %s and %s textures transform TEXCOORD_0 differently "
                        "(KHR_texture_transform); seamcook bakes one transform per material into the uv",
                        ctx, first, slots[i].slot);
        }
    }
    return SC_OK;
}


/* A primitive's TANGENT (optional, float VEC4, transformed like POSITION's
 * directions): for each corner of its triangles r->ntri .. + nt, does
 * w cross(N, T) run with increasing v (the GL uv the reader stores) or
 * against it? Counted per glTF material: a normal map baked against
 * bitangents that run against v stores its green channel the other way up
 * from the frames seamcook writes (sc_gltf_texture.green_flipped). */
static int count_tangent_convention(reader *r, const char *ctx, const cJSON *attributes, const mat4 m,
                                    int64_t material, int64_t base, int64_t n, int64_t nt) {
    int64_t tan_i = -1;
    int rc = get_ref(r, ctx, attributes, "TANGENT", &r->accessors, "accessor", false, &tan_i);
    if (rc != SC_OK || tan_i < 0 || !r->all_normals) return rc;
    accessor tan;
    if ((rc = open_accessor(r, tan_i, 4, "TANGENT", &tan))) return rc;
    if (tan.ctype != CT_F32 || tan.count != n) return SC_OK;   /* not usable: the frames built here serve */
    if (!r->tangent_with) {
        r->tangent_with = sc_calloc_array((size_t)r->materials.count + 1, sizeof *r->tangent_with);
        r->tangent_against = sc_calloc_array((size_t)r->materials.count + 1, sizeof *r->tangent_against);
        if (!r->tangent_with || !r->tangent_against) return fail(r, SC_ENOMEM, "out of memory");
    }
    double det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
                 m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
    for (int64_t t = 0; t < nt; t++) {
        const int32_t *c = r->tri + 3 * (r->ntri + t);
        const double *P0 = r->P + 3 * (size_t)c[0], *P1 = r->P + 3 * (size_t)c[1], *P2 = r->P + 3 * (size_t)c[2];
        const double *U0 = r->UV + 2 * (size_t)c[0], *U1 = r->UV + 2 * (size_t)c[1], *U2 = r->UV + 2 * (size_t)c[2];
        double s1 = U1[0] - U0[0], t1 = U1[1] - U0[1], s2 = U2[0] - U0[0], t2 = U2[1] - U0[1];
        double area = s1 * t2 - s2 * t1, dv[3];
        if (!(fabs(area) > 0)) continue;
        for (int k = 0; k < 3; k++) dv[k] = (s1 * (P2[k] - P0[k]) - s2 * (P1[k] - P0[k])) / area;
        for (int k = 0; k < 3; k++) {
            int64_t i = c[k] - base;
            double a = accessor_get(&tan, i, 0), b = accessor_get(&tan, i, 1), e = accessor_get(&tan, i, 2);
            double w = accessor_get(&tan, i, 3), T[3], B[3];
            if (!isfinite(a) || !isfinite(b) || !isfinite(e) || !isfinite(w) || w == 0) continue;
            for (int d = 0; d < 3; d++) T[d] = m[d][0] * a + m[d][1] * b + m[d][2] * e;
            const double *N = r->N + 3 * (size_t)c[k];
            B[0] = N[1] * T[2] - N[2] * T[1], B[1] = N[2] * T[0] - N[0] * T[2], B[2] = N[0] * T[1] - N[1] * T[0];
            double along = (w < 0 ? -1 : 1) * (det < 0 ? -1 : 1) * (B[0] * dv[0] + B[1] * dv[1] + B[2] * dv[2]);
            if (along > 0) r->tangent_with[material + 1]++;
            else if (along < 0) r->tangent_against[material + 1]++;
        }
    }
    return SC_OK;
}

static int add_primitive(reader *r, int64_t mesh, int64_t index, const cJSON *prim, const mat4 m) {
    char ctx[96];
    snprintf(ctx, sizeof ctx, "mesh %lld primitive %lld", (long long)mesh, (long long)index);
    if (!cJSON_IsObject(prim)) return fail(r, SC_EINPUT, "%s is not an object", ctx);
    int64_t mode = 0, pos_i = -1, uv_i = -1, nrm_i = -1, idx_i = -1, material = -1;
    int rc;
    if ((rc = get_int(r, ctx, prim, "mode", 4, 0, 6, &mode))) return rc;
    if (mode != 4) {
        r->primitives_skipped++;
        return SC_OK;
    }
    const cJSON *ext = field(prim, "extensions");
    if (field(ext, "KHR_draco_mesh_compression"))
        return fail(r, SC_EINPUT, "%s: Draco-compressed primitives are not supported", ctx);
    const cJSON *attributes = field(prim, "attributes");
    if (!cJSON_IsObject(attributes)) return fail(r, SC_EINPUT, "%s: 'attributes' is missing", ctx);
    if ((rc = get_ref(r, ctx, attributes, "POSITION", &r->accessors, "accessor", true, &pos_i)))
        return rc;
    /* without TEXCOORD_0 the uv are (0, 0): no area, which quad_chartify's auto mode replaces */
    if ((rc = get_ref(r, ctx, attributes, "TEXCOORD_0", &r->accessors, "accessor", false, &uv_i)) ||
        (rc = get_ref(r, ctx, attributes, "NORMAL", &r->accessors, "accessor", false, &nrm_i)) ||
        (rc = get_ref(r, ctx, prim, "indices", &r->accessors, "accessor", false, &idx_i)) ||
        (rc = get_ref(r, ctx, prim, "material", &r->materials, "material", false, &material)))
        return rc;
    uv_transform ut;
    if ((rc = material_transform(r, material, &ut))) return rc;
    accessor pos, uv = {0}, nrm, idx;
    if ((rc = open_accessor(r, pos_i, 3, "POSITION", &pos)) ||
        (uv_i >= 0 && (rc = open_accessor(r, uv_i, 2, "TEXCOORD_0", &uv))))
        return rc;
    /* KHR_mesh_quantization: positions and uv may be 8/16-bit integers, normalized or not, normals
     * normalized 8/16-bit signed integers (the node and texture transforms scale them back) */
    bool quantized = r->quantized;
    bool pos_int = pos.ctype == CT_I8 || pos.ctype == CT_U8 || pos.ctype == CT_I16 || pos.ctype == CT_U16;
    if (pos.ctype != CT_F32 && !(quantized && pos_int))
        return fail(r, SC_EINPUT, "accessor %lld: POSITION must be float%s", (long long)pos_i,
                    quantized ? " or 8/16-bit integers" : " (integers need KHR_mesh_quantization)");
    bool uv_int = uv.ctype == CT_I8 || uv.ctype == CT_U8 || uv.ctype == CT_I16 || uv.ctype == CT_U16;
    if (uv_i >= 0 && !(uv.ctype == CT_F32 || ((uv.ctype == CT_U8 || uv.ctype == CT_U16) && uv.normalized) ||
                       (quantized && uv_int)))
        return fail(r, SC_EINPUT, "accessor %lld: TEXCOORD_0 must be float or normalized u8/u16",
                    (long long)uv_i);
    if (uv_i >= 0 && uv.count != pos.count)
        return fail(r, SC_EINPUT, "%s: TEXCOORD_0 has %lld elements, POSITION %lld", ctx,
                    (long long)uv.count, (long long)pos.count);
    if (nrm_i >= 0) {
        if ((rc = open_accessor(r, nrm_i, 3, "NORMAL", &nrm))) return rc;
        bool nrm_int = (nrm.ctype == CT_I8 || nrm.ctype == CT_I16) && nrm.normalized;
        if (nrm.ctype != CT_F32 && !(quantized && nrm_int))
            return fail(r, SC_EINPUT, "accessor %lld: NORMAL must be float", (long long)nrm_i);
        if (nrm.count != pos.count)
            return fail(r, SC_EINPUT, "%s: NORMAL has %lld elements, POSITION %lld", ctx,
                        (long long)nrm.count, (long long)pos.count);
    } else {
        r->all_normals = false;
    }
    int64_t n = pos.count, base = r->nraw;
    if (base + n > SC_GLTF_MAX_ELEMENTS)
        return fail(r, SC_ENOMEM, "%s: more than %d vertices in the scene (the limit)", ctx,
                    SC_GLTF_MAX_ELEMENTS);
    if (!grow_array((void **)&r->P, &r->capP, 3 * (base + n), sizeof(double)) ||
        !grow_array((void **)&r->UV, &r->capUV, 2 * (base + n), sizeof(double)) ||
        (r->all_normals && !grow_array((void **)&r->N, &r->capN, 3 * (base + n), sizeof(double))))
        return fail(r, SC_ENOMEM, "out of memory");
    double nm[3][3];
    normal_matrix(m, nm);
    for (int64_t i = 0; i < n; i++) {
        double x = accessor_get(&pos, i, 0), y = accessor_get(&pos, i, 1), z = accessor_get(&pos, i, 2);
        double u = uv_i >= 0 ? accessor_get(&uv, i, 0) : 0, v = uv_i >= 0 ? accessor_get(&uv, i, 1) : 1;
        if (!isfinite(x) || !isfinite(y) || !isfinite(z))
            return fail(r, SC_EINPUT, "accessor %lld: POSITION %lld is not finite", (long long)pos_i, (long long)i);
        if (!isfinite(u) || !isfinite(v))
            return fail(r, SC_EINPUT, "accessor %lld: TEXCOORD_0 %lld is not finite", (long long)uv_i, (long long)i);
        double *p = r->P + 3 * (base + i);
        for (int k = 0; k < 3; k++) p[k] = x * m[k][0] + y * m[k][1] + z * m[k][2] + m[k][3];
        if (!isfinite(p[0]) || !isfinite(p[1]) || !isfinite(p[2]))
            return fail(r, SC_EINPUT, "%s: POSITION %lld is not finite after the node transform", ctx,
                        (long long)i);
        double tu = u, tv = v;   /* without TEXCOORD_0: (0, 1) in glTF's terms, stored as (0, 0) */
        if (uv_i >= 0) tu = ut.m[0] * u + ut.m[1] * v + ut.m[2], tv = ut.m[3] * u + ut.m[4] * v + ut.m[5];
        if (!isfinite(tu) || !isfinite(tv))
            return fail(r, SC_EINPUT, "%s: TEXCOORD_0 %lld is not finite after the material's texture transform", ctx,
                        (long long)i);
        r->UV[2 * (base + i)] = tu;
        r->UV[2 * (base + i) + 1] = 1.0 - tv;
        if (r->all_normals) {
            double a = accessor_get(&nrm, i, 0), b = accessor_get(&nrm, i, 1), c = accessor_get(&nrm, i, 2);
            if (!isfinite(a) || !isfinite(b) || !isfinite(c))
                return fail(r, SC_EINPUT, "accessor %lld: NORMAL %lld is not finite", (long long)nrm_i, (long long)i);
            double *q = r->N + 3 * (base + i), len = 0;
            for (int k = 0; k < 3; k++) {
                q[k] = nm[k][0] * a + nm[k][1] * b + nm[k][2] * c;
                len += q[k] * q[k];
            }
            len = sqrt(len);
            if (len > 0 && isfinite(len))
                for (int k = 0; k < 3; k++) q[k] /= len;
            for (int k = 0; k < 3; k++)
                if (!isfinite(q[k])) q[k] = 0;
        }
    }
    int64_t ncorner = n;
    if (idx_i >= 0) {
        if ((rc = open_accessor(r, idx_i, 1, "indices", &idx))) return rc;
        if (idx.ctype != CT_U8 && idx.ctype != CT_U16 && idx.ctype != CT_U32)
            return fail(r, SC_EINPUT, "accessor %lld: indices must be u8, u16 or u32", (long long)idx_i);
        ncorner = idx.count;
    }
    if (ncorner % 3)
        return fail(r, SC_EINPUT, "%s: %lld %s is not a multiple of 3", ctx, (long long)ncorner,
                    idx_i >= 0 ? "indices" : "vertices");
    int64_t nt = ncorner / 3;
    if (r->ntri + nt > SC_GLTF_MAX_ELEMENTS)
        return fail(r, SC_ENOMEM, "%s: more than %d triangles in the scene (the limit)", ctx,
                    SC_GLTF_MAX_ELEMENTS);
    if (!grow_array((void **)&r->tri, &r->captri, 3 * (r->ntri + nt), sizeof(int32_t)) ||
        !grow_array((void **)&r->tri_material, &r->captm, r->ntri + nt, sizeof(int32_t)))
        return fail(r, SC_ENOMEM, "out of memory");
    for (int64_t c = 0; c < ncorner; c++) {
        int64_t k = c;
        if (idx_i >= 0) {
            double d = accessor_get(&idx, c, 0);
            if (d >= (double)n)
                return fail(r, SC_EINPUT,
                            "accessor %lld: index %.0f at position %lld is out of range (the primitive has %lld vertices)",
                            (long long)idx_i, d, (long long)c, (long long)n);
            k = (int64_t)d;
        }
        r->tri[3 * r->ntri + c] = (int32_t)(base + k);
    }
    for (int64_t t = 0; t < nt; t++) r->tri_material[r->ntri + t] = (int32_t)material;
    if ((rc = count_tangent_convention(r, ctx, attributes, m, material, base, n, nt)) != SC_OK) return rc;
    if (uv_i < 0) r->faces_without_uv += nt;
    r->ntri += nt;
    r->nraw = base + n;
    return SC_OK;
}

static int visit_node(reader *r, int64_t n, const mat4 parent, int depth) {
    char ctx[64];
    snprintf(ctx, sizeof ctx, "node %lld", (long long)n);
    if (depth > MAX_NODE_DEPTH)
        return fail(r, SC_EINPUT, "%s: the node hierarchy is deeper than %d", ctx, MAX_NODE_DEPTH);
    if (r->on_path[n]) return fail(r, SC_EINPUT, "%s: the node hierarchy has a cycle", ctx);
    if (++r->node_visits > MAX_NODE_VISITS)
        return fail(r, SC_EINPUT, "%s: more than %d node instances", ctx, MAX_NODE_VISITS);
    const cJSON *node = r->nodes.items[n];
    mat4 local, world;
    int rc = node_matrix(r, ctx, node, local);
    if (rc) return rc;
    mat4_mul(parent, local, world);
    int64_t mesh = -1;
    if ((rc = get_ref(r, ctx, node, "mesh", &r->meshes, "mesh", false, &mesh))) return rc;
    if (mesh >= 0) {
        char mctx[64];
        snprintf(mctx, sizeof mctx, "mesh %lld", (long long)mesh);
        const cJSON *prims = field(r->meshes.items[mesh], "primitives");
        if (!cJSON_IsArray(prims)) return fail(r, SC_EINPUT, "%s: 'primitives' is not an array", mctx);
        int64_t i = 0;
        const cJSON *prim;
        cJSON_ArrayForEach(prim, prims) {
            if ((rc = add_primitive(r, mesh, i++, prim, world))) return rc;
        }
    }
    const cJSON *children = field(node, "children");
    if (children && !cJSON_IsArray(children))
        return fail(r, SC_EINPUT, "%s: 'children' is not an array", ctx);
    r->on_path[n] = true;
    const cJSON *child;
    cJSON_ArrayForEach(child, children) {
        double d = cJSON_IsNumber(child) ? child->valuedouble : -1;
        if (!(d == floor(d) && d >= 0 && d < (double)r->nodes.count)) {
            r->on_path[n] = false;
            return fail(r, SC_EINPUT, "%s: a child is not a node index", ctx);
        }
        if ((rc = visit_node(r, (int64_t)d, world, depth + 1))) break;
    }
    r->on_path[n] = false;
    return rc;
}

static int visit_scene(reader *r) {
    mat4 identity;
    mat4_identity(identity);
    int rc;
    if (r->scenes.count > 0) {
        int64_t scene = 0;
        if ((rc = get_ref(r, "file", r->root, "scene", &r->scenes, "scene", false, &scene))) return rc;
        if (scene < 0) scene = 0;
        char ctx[64];
        snprintf(ctx, sizeof ctx, "scene %lld", (long long)scene);
        const cJSON *nodes = field(r->scenes.items[scene], "nodes");
        if (nodes && !cJSON_IsArray(nodes)) return fail(r, SC_EINPUT, "%s: 'nodes' is not an array", ctx);
        const cJSON *e;
        cJSON_ArrayForEach(e, nodes) {
            double d = cJSON_IsNumber(e) ? e->valuedouble : -1;
            if (!(d == floor(d) && d >= 0 && d < (double)r->nodes.count))
                return fail(r, SC_EINPUT, "%s: a root is not a node index", ctx);
            if ((rc = visit_node(r, (int64_t)d, identity, 0))) return rc;
        }
        return SC_OK;
    }
    /* no scenes: every node that is no node's child */
    bool *is_child = calloc((size_t)r->nodes.count + 1, 1);
    if (!is_child) return fail(r, SC_ENOMEM, "out of memory");
    for (int64_t n = 0; n < r->nodes.count; n++) {
        const cJSON *e;
        cJSON_ArrayForEach(e, field(r->nodes.items[n], "children")) {
            double d = cJSON_IsNumber(e) ? e->valuedouble : -1;
            if (d == floor(d) && d >= 0 && d < (double)r->nodes.count) is_child[(int64_t)d] = true;
        }
    }
    rc = SC_OK;
    for (int64_t n = 0; n < r->nodes.count && rc == SC_OK; n++)
        if (!is_child[n]) rc = visit_node(r, n, identity, 0);
    free(is_child);
    return rc;
}

/* ---------------------------------------------------------------- welding */

typedef struct weld_table {
    int32_t *slots;
    uint64_t mask;
    double *keys;   /* dim doubles per distinct key */
    int dim;
    int32_t count;
} weld_table;

static uint64_t mix64(uint64_t x) {
    x ^= x >> 33;
    x *= 0xff51afd7ed558ccdull;
    x ^= x >> 33;
    x *= 0xc4ceb9fe1a85ec53ull;
    x ^= x >> 33;
    return x;
}

static bool weld_init(weld_table *w, int dim, int64_t max_keys) {
    uint64_t n = 16;
    while (n < (uint64_t)max_keys * 2) n *= 2;
    w->slots = sc_alloc_array((size_t)n, sizeof(int32_t));
    w->keys = sc_alloc_array((size_t)max_keys * (size_t)dim, sizeof(double));
    w->mask = n - 1;
    w->dim = dim;
    w->count = 0;
    if (!w->slots || !w->keys) return false;
    memset(w->slots, 0xff, (size_t)n * sizeof(int32_t));
    return true;
}

static void weld_free(weld_table *w) {
    free(w->slots);
    free(w->keys);
}

/* The number of key (dim doubles, -0 folded into +0), adding it when new. */
static int32_t weld_add(weld_table *w, const double *key_in) {
    double key[3];
    uint64_t h = 0x9e3779b97f4a7c15ull;
    for (int d = 0; d < w->dim; d++) {
        key[d] = key_in[d] + 0.0;
        uint64_t bits;
        memcpy(&bits, &key[d], 8);
        h = mix64(h ^ bits) + (uint64_t)d;
    }
    for (uint64_t i = h & w->mask;; i = (i + 1) & w->mask) {
        int32_t k = w->slots[i];
        if (k < 0) {
            memcpy(w->keys + (size_t)w->count * (size_t)w->dim, key, sizeof(double) * (size_t)w->dim);
            w->slots[i] = w->count;
            return w->count++;
        }
        if (memcmp(w->keys + (size_t)k * (size_t)w->dim, key, sizeof(double) * (size_t)w->dim) == 0)
            return k;
    }
}

/* ---------------------------------------------------------------- materials, images */

static int add_image(reader *r, int64_t i, sc_gltf *out, int32_t *slot) {
    for (int32_t k = 0; k < out->nimages; k++)
        if (out->images[k].index == i) {
            *slot = k;
            return SC_OK;
        }
    char ctx[64];
    snprintf(ctx, sizeof ctx, "image %lld", (long long)i);
    sc_gltf_image *images = sc_realloc_array(out->images, (size_t)out->nimages + 1, sizeof *images);
    if (!images) return fail(r, SC_ENOMEM, "out of memory");
    out->images = images;
    sc_gltf_image *im = &images[out->nimages];
    memset(im, 0, sizeof *im);
    im->index = (int32_t)i;
    const cJSON *obj = r->images.items[i];
    const cJSON *uri = field(obj, "uri");
    int64_t view = -1;
    int rc = SC_OK;
    if (uri) {
        if (!cJSON_IsString(uri)) return fail(r, SC_EINPUT, "%s: 'uri' is not a string", ctx);
        if (strncmp(uri->valuestring, "data:", 5) == 0)
            rc = decode_data_uri(r, ctx, uri->valuestring, &im->data, &im->size);
        else
            rc = uri_to_path(r, ctx, uri->valuestring, &im->path);
    } else if ((rc = get_ref(r, ctx, obj, "bufferView", &r->views, "bufferView", false, &view)) == SC_OK) {
        if (view < 0) return fail(r, SC_EINPUT, "%s has neither a uri nor a bufferView", ctx);
        const uint8_t *bytes = NULL;
        size_t len = 0;
        if ((rc = open_view(r, ctx, view, &bytes, &len, NULL)) == SC_OK) {
            im->data = malloc(len);
            if (!im->data) return fail(r, SC_ENOMEM, "out of memory");
            memcpy(im->data, bytes, len);
            im->size = len;
        }
    }
    if (rc) {
        free(im->data);
        free(im->path);
        return rc;
    }
    *slot = out->nimages++;
    return SC_OK;
}

static int wrap_mode(reader *r, const char *ctx, const cJSON *sampler, const char *key, sc_wrap *out) {
    int64_t v = 0;
    int rc = get_int(r, ctx, sampler, key, 10497, 0, 1 << 20, &v);
    if (rc) return rc;
    switch (v) {
    case 10497: *out = SC_WRAP_REPEAT; return SC_OK;
    case 33071: *out = SC_WRAP_CLAMP; return SC_OK;
    case 33648: *out = SC_WRAP_MIRROR; return SC_OK;
    }
    return fail(r, SC_EINPUT, "%s: %s %lld is not a glTF wrap mode", ctx, key, (long long)v);
}

static int add_texture(reader *r, const char *mctx, const cJSON *info, const char *slot, int64_t gm,
                       int32_t material, sc_gltf *out) {
    if (!info) return SC_OK;
    if (!cJSON_IsObject(info)) return fail(r, SC_EINPUT, "%s: the %s texture is not an object", mctx, slot);
    int64_t tex = -1, texcoord = 0, source = -1, sampler = -1;
    int rc;
    uv_transform unused;
    if ((rc = get_ref(r, mctx, info, "index", &r->textures, "texture", true, &tex)) ||
        (rc = texture_transform(r, mctx, slot, info, &unused, &texcoord)))
        return rc;
    if (texcoord != 0) {
        out->textures_skipped++;
        return SC_OK;
    }
    char ctx[64];
    snprintf(ctx, sizeof ctx, "texture %lld", (long long)tex);
    const cJSON *t = r->textures.items[tex];
    if ((rc = get_ref(r, ctx, t, "source", &r->images, "image", false, &source)) ||
        (rc = get_ref(r, ctx, t, "sampler", &r->samplers, "sampler", false, &sampler)))
        return rc;
    if (source < 0) {   /* EXT_texture_webp names its image in an extension (without a PNG/JPEG fallback) */
        const cJSON *webp = field(field(t, "extensions"), "EXT_texture_webp");
        if (webp && (rc = get_ref(r, ctx, webp, "source", &r->images, "image", true, &source))) return rc;
    }
    if (source < 0)
        return fail(r, SC_EINPUT, "%s has no source image (PNG, JPEG and EXT_texture_webp sources are supported)", ctx);
    sc_wrap wrap_u = SC_WRAP_REPEAT, wrap_v = SC_WRAP_REPEAT;
    if (sampler >= 0) {
        char sctx[64];
        snprintf(sctx, sizeof sctx, "sampler %lld", (long long)sampler);
        if ((rc = wrap_mode(r, sctx, r->samplers.items[sampler], "wrapS", &wrap_u)) ||
            (rc = wrap_mode(r, sctx, r->samplers.items[sampler], "wrapT", &wrap_v)))
            return rc;
    }
    int32_t image = -1;
    if ((rc = add_image(r, source, out, &image))) return rc;
    sc_gltf_texture *list_ = sc_realloc_array(out->textures, (size_t)out->ntextures + 1, sizeof *list_);
    if (!list_) return fail(r, SC_ENOMEM, "out of memory");
    out->textures = list_;
    sc_gltf_texture *x = &list_[out->ntextures];
    x->material = material;
    x->slot = sc_strdup(slot);
    x->image = image;
    x->wrap_u = wrap_u, x->wrap_v = wrap_v;
    x->green_flipped = strcmp(slot, "normal") == 0 && r->tangent_with &&
                       r->tangent_against[gm + 1] > r->tangent_with[gm + 1];
    if (!x->slot) return fail(r, SC_ENOMEM, "out of memory");
    out->ntextures++;
    return SC_OK;
}

static int add_material_textures(reader *r, int64_t gm, int32_t material, sc_gltf *out) {
    char ctx[64];
    snprintf(ctx, sizeof ctx, "material %lld", (long long)gm);
    const cJSON *m = r->materials.items[gm];
    const cJSON *pbr = field(m, "pbrMetallicRoughness");
    const cJSON *color = field(pbr, "baseColorTexture");
    if (!color)
        color = field(field(field(m, "extensions"), "KHR_materials_pbrSpecularGlossiness"), "diffuseTexture");
    int rc;
    if ((rc = add_texture(r, ctx, color, "color", gm, material, out)) ||
        (rc = add_texture(r, ctx, field(m, "normalTexture"), "normal", gm, material, out)) ||
        (rc = add_texture(r, ctx, field(m, "emissiveTexture"), "emissive", gm, material, out)) ||
        (rc = add_texture(r, ctx, field(m, "occlusionTexture"), "occlusion", gm, material, out)) ||
        (rc = add_texture(r, ctx, field(pbr, "metallicRoughnessTexture"), "metallic_roughness", gm, material, out)))
        return rc;
    return SC_OK;
}

/* ---------------------------------------------------------------- the file */

static uint32_t read_u32le(const uint8_t *p) {
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

/* Find the JSON text (and a .glb's binary chunk); parse it into r->root. */
static int parse_container(reader *r, const uint8_t *bytes, size_t size) {
    const uint8_t *json = bytes;
    size_t json_size = size;
    if (size >= 4 && memcmp(bytes, "glTF", 4) == 0) {
        if (size < 20) return fail(r, SC_EINPUT, "truncated: a .glb needs at least 20 bytes, got %zu", size);
        uint32_t version = read_u32le(bytes + 4), length = read_u32le(bytes + 8);
        if (version != 2) return fail(r, SC_EINPUT, "GLB version %u is not 2", version);
        if (length > size)
            return fail(r, SC_EINPUT, "truncated: the GLB header says %u bytes, got %zu", length, size);
        if (length < 20) return fail(r, SC_EINPUT, "GLB length %u is too small", length);
        uint32_t chunk = read_u32le(bytes + 12), type = read_u32le(bytes + 16);
        if (type != 0x4E4F534Au) return fail(r, SC_EINPUT, "the first GLB chunk is not JSON");
        if (chunk > length - 20)
            return fail(r, SC_EINPUT, "the GLB JSON chunk (%u bytes) runs past the end (%u)", chunk, length);
        json = bytes + 20;
        json_size = chunk;
        size_t next = 20 + (size_t)chunk;
        if (next + 8 <= length) {
            uint32_t bin = read_u32le(bytes + next), bin_type = read_u32le(bytes + next + 4);
            if (bin_type == 0x004E4942u) {
                if (bin > length - next - 8)
                    return fail(r, SC_EINPUT, "the GLB binary chunk (%u bytes) runs past the end (%u)", bin, length);
                r->glb_bin = bytes + next + 8;
                r->glb_bin_size = bin;
                r->has_glb_bin = true;
            }
        }
    }
    /* parse a NUL-terminated copy: the caller's bytes need not end in NUL */
    char *text = sc_strndup((const char *)json, json_size);
    if (!text) return fail(r, SC_ENOMEM, "out of memory");
    const char *end = NULL;
    r->root = cJSON_ParseWithLengthOpts(text, json_size, &end, false);
    if (!r->root) {
        int line = 1;
        size_t at = (end && end >= text && end <= text + json_size) ? (size_t)(end - text) : 0;
        for (size_t i = 0; i < at; i++) line += text[i] == '\n';
        free(text);
        return fail(r, SC_EINPUT, "JSON syntax error at line %d (byte %zu)", line, at);
    }
    free(text);
    if (!cJSON_IsObject(r->root)) return fail(r, SC_EINPUT, "the JSON is not an object");
    const cJSON *version = field(field(r->root, "asset"), "version");
    if (!cJSON_IsString(version)) return fail(r, SC_EINPUT, "no asset.version: not a glTF file");
    if (strncmp(version->valuestring, "2.", 2) != 0)
        return fail(r, SC_EINPUT, "asset.version is %.20s, only glTF 2.0 is supported", version->valuestring);
    const cJSON *e;
    cJSON_ArrayForEach(e, field(r->root, "extensionsRequired")) {
        if (!cJSON_IsString(e)) return fail(r, SC_EINPUT, "extensionsRequired has a non-string entry");
        const char *x = e->valuestring;
        if (strncmp(x, "KHR_materials_", 14) != 0 && strcmp(x, "KHR_mesh_quantization") != 0 &&
            strcmp(x, "KHR_texture_transform") != 0 && strcmp(x, "EXT_texture_webp") != 0)
            return fail(r, SC_EINPUT, "requires extension %.60s, which seamcook does not support", e->valuestring);
    }
    cJSON_ArrayForEach(e, field(r->root, "extensionsUsed"))
        if (cJSON_IsString(e) && strcmp(e->valuestring, "KHR_mesh_quantization") == 0) r->quantized = true;
    return SC_OK;
}

/* Material k's constants (glTF 2.0 material: factors, scale and strength
 * of its textures, alphaMode, alphaCutoff, doubleSided) into *m. */
static int material_constants(reader *r, int64_t k, sc_material *m) {
    char ctx[48];
    snprintf(ctx, sizeof ctx, "material %lld", (long long)k);
    const cJSON *mat = r->materials.items[k], *pbr = field(mat, "pbrMetallicRoughness");
    int rc;
    if ((rc = get_numbers(r, ctx, pbr, "baseColorFactor", 4, m->base_color, NULL)) ||
        (rc = get_number(r, ctx, pbr, "metallicFactor", 0, 1, &m->metallic)) ||
        (rc = get_number(r, ctx, pbr, "roughnessFactor", 0, 1, &m->roughness)) ||
        (rc = get_numbers(r, ctx, mat, "emissiveFactor", 3, m->emissive, NULL)) ||
        (rc = get_number(r, ctx, field(mat, "normalTexture"), "scale", -1e6, 1e6, &m->normal_scale)) ||
        (rc = get_number(r, ctx, field(mat, "occlusionTexture"), "strength", 0, 1, &m->occlusion_strength)) ||
        (rc = get_number(r, ctx, mat, "alphaCutoff", 0, 1e6, &m->alpha_cutoff)))
        return rc;
    const cJSON *mode = field(mat, "alphaMode"), *sided = field(mat, "doubleSided");
    if (mode) {
        const char *s = cJSON_IsString(mode) ? mode->valuestring : "";
        if (strcmp(s, "OPAQUE") == 0) m->alpha_mode = SC_ALPHA_OPAQUE;
        else if (strcmp(s, "MASK") == 0) m->alpha_mode = SC_ALPHA_MASK;
        else if (strcmp(s, "BLEND") == 0) m->alpha_mode = SC_ALPHA_BLEND;
        else return fail(r, SC_EINPUT, "%s: 'alphaMode' must be OPAQUE, MASK or BLEND", ctx);
    }
    if (sided) {
        if (!cJSON_IsBool(sided)) return fail(r, SC_EINPUT, "%s: 'doubleSided' must be true or false", ctx);
        m->double_sided = cJSON_IsTrue(sided);
    }
    for (int c = 0; c < 4; c++)
        if (!(m->base_color[c] >= 0 && m->base_color[c] <= 1))
            return fail(r, SC_EINPUT, "%s: 'baseColorFactor' must hold numbers in [0, 1]", ctx);
    for (int c = 0; c < 3; c++)
        if (!(m->emissive[c] >= 0))
            return fail(r, SC_EINPUT, "%s: 'emissiveFactor' must hold numbers of at least 0", ctx);
    return SC_OK;
}

/* Weld, map materials, build the mesh and the texture list. */
static int build(reader *r, sc_gltf *out) {
    if (r->ntri == 0) return fail(r, SC_EINPUT, "the scene has no triangles");
    int32_t *vid = sc_alloc_array((size_t)r->nraw, sizeof(int32_t));
    int32_t *uid = sc_alloc_array((size_t)r->nraw, sizeof(int32_t));
    int32_t *FV = sc_alloc_array((size_t)r->ntri * 3, sizeof(int32_t));
    int32_t *FU = sc_alloc_array((size_t)r->ntri * 3, sizeof(int32_t));
    int32_t *FM = sc_alloc_array((size_t)r->ntri, sizeof(int32_t));
    int32_t *mat_map = sc_alloc_array((size_t)r->materials.count + 1, sizeof(int32_t));
    char **names = sc_calloc_array((size_t)r->materials.count + 1, sizeof(char *));
    weld_table wv = {0}, wu = {0};
    int rc = SC_OK;
    if (!vid || !uid || !FV || !FU || !FM || !mat_map || !names || !weld_init(&wv, 3, r->nraw) ||
        !weld_init(&wu, 3, r->nraw)) {
        rc = fail(r, SC_ENOMEM, "out of memory");
        goto done;
    }
    for (int64_t i = 0; i < r->nraw; i++) {
        vid[i] = weld_add(&wv, r->P + 3 * i);
        double key[3] = {(double)vid[i], r->UV[2 * i], r->UV[2 * i + 1]};
        uid[i] = weld_add(&wu, key);
    }
    double *U = sc_alloc_array((size_t)wu.count * 2 + 1, sizeof(double));
    if (!U) {
        rc = fail(r, SC_ENOMEM, "out of memory");
        goto done;
    }
    for (int32_t k = 0; k < wu.count; k++) U[2 * k] = wu.keys[3 * k + 1], U[2 * k + 1] = wu.keys[3 * k + 2];
    /* materials: the used glTF ones in glTF order, then "default" */
    int64_t nm = r->materials.count;
    for (int64_t k = 0; k <= nm; k++) mat_map[k] = -1;
    for (int64_t t = 0; t < r->ntri; t++) {
        int32_t g = r->tri_material[t];
        mat_map[g < 0 ? nm : g] = 0;
    }
    int32_t nmat = 0;
    for (int64_t k = 0; k <= nm && rc == SC_OK; k++) {
        if (mat_map[k] < 0) continue;
        const cJSON *name = k < nm ? field(r->materials.items[k], "name") : NULL;
        char *s = k == nm ? sc_strdup("default")
                  : (cJSON_IsString(name) && name->valuestring[0]) ? sc_strdup(name->valuestring)
                  : sc_strprintf("material%lld", (long long)k);
        for (int32_t j = 0; s && j < nmat; j++)
            if (strcmp(names[j], s) == 0) {   /* keep names distinct */
                char *t = sc_strprintf("%s_%lld", s, (long long)k);
                free(s);
                s = t;
                j = -1;
            }
        if (!s) rc = fail(r, SC_ENOMEM, "out of memory");
        else names[nmat] = s, mat_map[k] = nmat++;
    }
    for (int64_t t = 0; t < r->ntri && rc == SC_OK; t++) {
        int32_t g = r->tri_material[t];
        FM[t] = mat_map[g < 0 ? nm : g];
        for (int k = 0; k < 3; k++) {
            FV[3 * t + k] = vid[r->tri[3 * t + k]];
            FU[3 * t + k] = uid[r->tri[3 * t + k]];
        }
    }
    if (rc == SC_OK) {
        rc = sc_mesh_build_compact(wv.keys, wv.count, U, wu.count, r->all_normals ? r->N : NULL,
                                   r->nraw, FV, FU, r->all_normals ? r->tri : NULL, FM, r->ntri,
                                   names, nmat, &out->mesh, &out->degenerate_faces_dropped, NULL,
                                   r->err);
        if (rc != SC_OK) sc_error_prefix(r->err, "%s", r->name);
    }
    if (rc == SC_OK && !(out->materials = sc_alloc_array((size_t)nmat + 1, sizeof *out->materials)))
        rc = fail(r, SC_ENOMEM, "out of memory");
    for (int64_t k = 0; k <= nm && rc == SC_OK; k++)
        if (mat_map[k] >= 0) {
            out->materials[mat_map[k]] = sc_material_default();   /* "default": glTF's default material */
            if (k < nm) rc = material_constants(r, k, &out->materials[mat_map[k]]);
        }
    for (int64_t k = 0; k < nm && rc == SC_OK; k++)
        if (mat_map[k] >= 0) rc = add_material_textures(r, k, mat_map[k], out);
    free(U);
done:
    if (names)
        for (int64_t k = 0; k <= r->materials.count; k++) free(names[k]);
    free(names), free(mat_map);
    free(vid), free(uid), free(FV), free(FU), free(FM);
    weld_free(&wv), weld_free(&wu);
    return rc;
}

int sc_gltf_parse(const char *name, const void *bytes, size_t size, sc_gltf_read_fn read,
                  void *ud, sc_gltf *out, sc_error *err) {
    memset(out, 0, sizeof *out);
    reader r;
    memset(&r, 0, sizeof r);
    r.name = name;
    r.err = err;
    r.read = read;
    r.ud = ud;
    r.all_normals = true;
    int rc = parse_container(&r, bytes ? bytes : (const void *)"", bytes ? size : 0);
    if (rc == SC_OK &&
        ((rc = index_list(&r, "accessors", &r.accessors)) || (rc = index_list(&r, "bufferViews", &r.views)) ||
         (rc = index_list(&r, "buffers", &r.buffers)) || (rc = index_list(&r, "nodes", &r.nodes)) ||
         (rc = index_list(&r, "meshes", &r.meshes)) || (rc = index_list(&r, "materials", &r.materials)) ||
         (rc = index_list(&r, "textures", &r.textures)) || (rc = index_list(&r, "images", &r.images)) ||
         (rc = index_list(&r, "samplers", &r.samplers)) || (rc = index_list(&r, "scenes", &r.scenes))) == SC_OK) {
        r.bufs = calloc((size_t)r.buffers.count + 1, sizeof *r.bufs);
        r.on_path = calloc((size_t)r.nodes.count + 1, sizeof *r.on_path);
        if (!r.bufs || !r.on_path) rc = fail(&r, SC_ENOMEM, "out of memory");
    }
    if (rc == SC_OK) rc = visit_scene(&r);
    if (rc == SC_OK) rc = build(&r, out);
    out->primitives_skipped = r.primitives_skipped;
    out->faces_without_uv = r.faces_without_uv;
    out->uv_missing = r.ntri > 0 && r.faces_without_uv == r.ntri;
    out->raw_vertices = r.nraw;
    for (int64_t i = 0; r.bufs && i < r.buffers.count; i++) free(r.bufs[i].owned);
    free(r.bufs);
    free(r.on_path);
    list *lists[] = {&r.accessors, &r.views, &r.buffers, &r.nodes, &r.meshes,
                     &r.materials, &r.textures, &r.images, &r.samplers, &r.scenes};
    for (size_t i = 0; i < sizeof lists / sizeof lists[0]; i++) free(lists[i]->items);
    free(r.P), free(r.UV), free(r.N), free(r.tri), free(r.tri_material);
    free(r.tangent_with), free(r.tangent_against);
    cJSON_Delete(r.root);
    if (rc != SC_OK) sc_gltf_free(out);
    return rc;
}

void sc_gltf_free(sc_gltf *g) {
    if (!g) return;
    sc_mesh_free(g->mesh);
    for (int32_t i = 0; i < g->nimages; i++) {
        free(g->images[i].path);
        free(g->images[i].data);
    }
    free(g->images);
    for (int32_t i = 0; i < g->ntextures; i++) free(g->textures[i].slot);
    free(g->textures);
    free(g->materials);
    memset(g, 0, sizeof *g);
}
