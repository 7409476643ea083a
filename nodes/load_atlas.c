/* load_atlas.c - the node `load_atlas`: a textured mesh from an OBJ or glTF file.
 *
 * Design note. The node is glue around three readers that never touch the
 * file system themselves (sc_obj, sc_gltf, sc_imageio): every file it needs,
 * the model, an MTL, a glTF buffer, each texture, goes through
 * sc_ctx_read_file, so the cache records exactly which bytes the atlas came
 * from. The parser is picked by extension (.obj, .gltf, .glb). Textures are
 * gathered as (material, slot, file) references first; each distinct file is
 * read once (in reference order, on the calling thread, as the context is not
 * thread-safe) and then decoded, in parallel up to sc_ctx_threads, into one
 * IMAGE value that every reference to it shares. Results never depend on the
 * thread count: each decode is independent, and the first failure in
 * reference order is the one reported.
 *
 * Slots: "color" and "emissive" are colour (sRGB when 8/16-bit); "normal",
 * "occlusion" and "metallic_roughness" are data, and their images are tagged
 * SC_COLOR_DATA so no later step applies a transfer curve to them. A glTF
 * normal map whose material's TANGENT bitangents mostly run against
 * increasing v (sc_gltf_texture.green_flipped) is given with its green
 * channel turned the other way up, so that it reads right through the
 * MikkTSpace frames every later step and the glTF writer use; the metric
 * normal_maps_green_flipped counts them.
 *
 * Metrics: the mesh's counts, seam and boundary edges (meshstats.py's
 * definitions: an edge of two or more faces is a seam when its faces do not
 * all use the same pair of uv indices at its endpoints; a boundary edge has
 * one face), what the readers repaired, and the time spent parsing and
 * decoding (report only, never in the output value).
 */
#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <strings.h>

#include "sc_gltf.h"
#include "sc_imageio.h"
#include "sc_nodes.h"
#include "sc_obj.h"
#include "sc_topology.h"

#define MAX_MODEL_BYTES ((size_t)2 << 30)
#define MAX_IMAGE_BYTES ((size_t)1 << 30)

static const char *const slot_names[] = {"color", "normal", "emissive", "occlusion",
                                         "metallic_roughness"};
#define NSLOTS ((int)(sizeof slot_names / sizeof slot_names[0]))

static int slot_index(const char *name, size_t len) {
    for (int s = 0; s < NSLOTS; s++)
        if (strlen(slot_names[s]) == len && strncmp(slot_names[s], name, len) == 0) return s;
    return -1;
}

static bool slot_is_colour(int slot) { return slot == 0 || slot == 2; }

/* ---------------------------------------------------------------- file access */

typedef struct file_reader {
    sc_ctx *ctx;
    const char *dir;    /* the model's directory */
    const char *root;   /* every file the model names must lie inside it */
} file_reader;

/* A file the model (or its MTL) names, resolved and confined to the root. */
static int resolve(const file_reader *fr, const char *rel, char **path, sc_error *err) {
    return sc_path_confine(fr->root, fr->dir, rel, path, err);
}

static bool regular_file(const char *path) {
    struct stat st;
    return stat(path, &st) == 0 && S_ISREG(st.st_mode);
}

/* A texture file the model names, resolved and confined to the root. A name
 * that is absolute or leads outside the root, or a file that is not there
 * (an export from another machine: "C:\Users\me\wood.png",
 * "../textures/wood.png"), falls back to the file of its base name beside
 * the model when that one is there, with a warning naming `origin`. */
static int resolve_texture(const file_reader *fr, const char *rel, const char *origin, char **path, sc_error *err) {
    sc_error first = {0};
    int rc = resolve(fr, rel, path, &first);
    if (rc == SC_OK && regular_file(*path)) return SC_OK;
    const char *base = rel + strlen(rel);
    while (base > rel && base[-1] != '/' && base[-1] != '\\') base--;
    char *beside = NULL;
    sc_error ignored = {0};
    if (base != rel && *base && resolve(fr, base, &beside, &ignored) == SC_OK && regular_file(beside)) {
        sc_ctx_warn(fr->ctx, "%s: '%s' %s: read %s, beside the model", origin, rel,
                    rc == SC_OK ? "is not there" : "is outside the asset's folder", base);
        free(*path);
        *path = beside;
        return SC_OK;
    }
    free(beside);
    if (rc != SC_OK) *err = first;
    return rc;   /* a missing file fails where it is read, naming it */
}

static int read_beside_model(void *ud, const char *rel, sc_buf *out, sc_error *err) {
    file_reader *fr = ud;
    char *path;
    int rc = resolve(fr, rel, &path, err);
    if (rc == SC_OK) rc = sc_ctx_read_file(fr->ctx, path, MAX_MODEL_BYTES, out, err);
    free(path);
    return rc;
}

/* ---------------------------------------------------------------- texture references */

typedef struct texref {
    int32_t material;
    int slot;
    char *path;              /* file to read (resolved), or NULL when embedded */
    const uint8_t *data;     /* embedded bytes (owned by the parse result) */
    size_t size;
    sc_wrap wrap_u, wrap_v;
    char *origin;            /* who names it, for messages: "a.mtl:12", "a.gltf" */
    int job;                 /* index into the decode jobs */
    bool green_flipped;      /* a normal map stored with its green channel the other way up */
} texref;

typedef struct decode_job {
    const char *path;        /* borrowed from the first texref */
    const uint8_t *data;     /* embedded, or the bytes read */
    size_t size;
    sc_colorspace colorspace;
    sc_buf bytes;
    sc_image_data *image;
    sc_value *value;
    int rc;                  /* of reading, then of decoding */
    sc_error err;
} decode_job;

typedef struct loaded {
    sc_mesh *mesh;           /* owned until wrapped */
    texref *refs;
    int nrefs;
    sc_obj obj;
    sc_gltf gltf;
    decode_job *jobs;
    int njobs;
} loaded;

static void loaded_free(loaded *l) {
    for (int i = 0; i < l->nrefs; i++) free(l->refs[i].path), free(l->refs[i].origin);
    free(l->refs);
    for (int i = 0; i < l->njobs; i++) {
        sc_buf_free(&l->jobs[i].bytes);
        sc_image_free(l->jobs[i].image);
        sc_value_release(l->jobs[i].value);
    }
    free(l->jobs);
    sc_mesh_free(l->mesh);
    sc_obj_free(&l->obj);
    sc_gltf_free(&l->gltf);
}

static int add_ref(loaded *l, int32_t material, int slot, char *path, const uint8_t *data,
                   size_t size, sc_wrap wu, sc_wrap wv, char *origin, sc_error *err) {
    texref *r = realloc(l->refs, sizeof *r * (size_t)(l->nrefs + 1));
    if (!r || !origin || (!path && !data)) {
        free(path), free(origin);
        if (r) l->refs = r;
        return sc_fail(err, SC_ENOMEM, "out of memory");
    }
    l->refs = r;
    r += l->nrefs++;
    r->material = material, r->slot = slot;
    r->path = path, r->data = data, r->size = size;
    r->wrap_u = wu, r->wrap_v = wv;
    r->origin = origin;
    r->job = -1;
    r->green_flipped = false;
    return SC_OK;
}

/* Which slots the `slots` parameter asks for. */
static int parse_slots(const char *text, bool wanted[NSLOTS], sc_error *err) {
    bool all = strcmp(text, "all") == 0;
    for (int s = 0; s < NSLOTS; s++) wanted[s] = all;
    if (all) return SC_OK;
    for (const char *p = text; *p;) {
        while (*p == ',' || *p == ' ') p++;
        size_t n = 0;
        while (p[n] && p[n] != ',' && p[n] != ' ') n++;
        if (!n) break;
        int s = slot_index(p, n);
        if (s < 0)
            return sc_fail(err, SC_EINPUT,
                           "unknown slot '%.*s' (known: all, color, normal, emissive, "
                           "occlusion, metallic_roughness)",
                           (int)n, p);
        wanted[s] = true;
        p += n;
    }
    return SC_OK;
}

static int check_slots(const char *text, sc_error *err) {
    bool wanted[NSLOTS];
    return parse_slots(text, wanted, err);
}

/* ---------------------------------------------------------------- parsing */

static int load_obj(file_reader *fr, const char *path, const sc_buf *bytes, const bool wanted[NSLOTS], loaded *l,
                    sc_error *err) {
    int rc = sc_obj_parse(path, bytes->data, bytes->len, read_beside_model, fr, &l->obj, err);
    if (rc) return rc;
    l->mesh = l->obj.mesh;
    l->obj.mesh = NULL;
    for (int32_t i = 0; i < l->obj.nmaps; i++) {
        const sc_obj_map *m = &l->obj.maps[i];
        int slot = slot_index(m->slot, strlen(m->slot));
        if (slot < 0 || !wanted[slot]) continue;
        char *mtl_path = strcmp(fr->dir, ".") == 0 ? sc_strdup(m->mtl) : sc_path_join(fr->dir, m->mtl);
        char *origin = mtl_path ? sc_strprintf("%s:%d", mtl_path, m->line) : NULL;
        free(mtl_path);
        char *file = NULL;
        if ((rc = resolve_texture(fr, m->path, origin ? origin : m->mtl, &file, err))) {
            sc_error_prefix(err, "%s: %s", origin ? origin : "", m->slot);
            free(origin);
            return rc;
        }
        if ((rc = add_ref(l, m->material, slot, file, NULL, 0, SC_WRAP_REPEAT, SC_WRAP_REPEAT, origin, err)))
            return rc;
    }
    sc_ctx_metric(fr->ctx, "polygons_triangulated", (double)l->obj.polygons);
    sc_ctx_metric(fr->ctx, "unreferenced_dropped", (double)l->obj.unreferenced_dropped);
    return SC_OK;
}

static int load_gltf(file_reader *fr, const char *path, const sc_buf *bytes, const bool wanted[NSLOTS], loaded *l,
                     sc_error *err) {
    int rc = sc_gltf_parse(path, bytes->data, bytes->len, read_beside_model, fr, &l->gltf, err);
    if (rc) return rc;
    l->mesh = l->gltf.mesh;
    l->gltf.mesh = NULL;
    for (int32_t i = 0; i < l->gltf.ntextures; i++) {
        const sc_gltf_texture *t = &l->gltf.textures[i];
        const sc_gltf_image *im = &l->gltf.images[t->image];
        int slot = slot_index(t->slot, strlen(t->slot));
        if (slot < 0 || !wanted[slot]) continue;
        char *file = NULL, *origin = sc_strprintf("%s: image %d", path, im->index);
        rc = im->path ? resolve_texture(fr, im->path, origin ? origin : path, &file, err) : SC_OK;
        if (rc) {
            free(origin);
            return sc_error_prefix(err, "%s: image %d", path, im->index);
        }
        if ((rc = add_ref(l, t->material, slot, file, im->data, im->size, t->wrap_u, t->wrap_v, origin, err)))
            return rc;
        l->refs[l->nrefs - 1].green_flipped = t->green_flipped;
    }
    sc_ctx_metric(fr->ctx, "primitives_skipped", (double)l->gltf.primitives_skipped);
    sc_ctx_metric(fr->ctx, "textures_skipped", (double)l->gltf.textures_skipped);
    return SC_OK;
}

/* A copy of normal map im with channel 1 the other way up (g -> 1 - g in
 * the stored range; -g for a signed float map), as a new value; NULL when
 * out of memory. */
static sc_value *green_flipped_copy(const sc_image_data *im) {
    sc_image_data *c = sc_image_alloc(im->width, im->height, im->channels, im->pixel);
    if (!c) return NULL;
    c->colorspace = im->colorspace;
    memcpy(c->format, im->format, sizeof c->format);
    size_t n = (size_t)im->width * im->height, C = (size_t)im->channels;
    memcpy(c->pixels, im->pixels, n * C * (size_t)im->pixel);
    bool is_signed = false;
    if (im->pixel == SC_PIXEL_F32)
        for (size_t i = 0; i < n * C && !is_signed; i++) is_signed = ((const float *)im->pixels)[i] < 0;
    for (size_t i = 0; C >= 2 && i < n; i++) {
        if (im->pixel == SC_PIXEL_U8) ((uint8_t *)c->pixels)[i * C + 1] = (uint8_t)(255 - ((uint8_t *)c->pixels)[i * C + 1]);
        else if (im->pixel == SC_PIXEL_U16)
            ((uint16_t *)c->pixels)[i * C + 1] = (uint16_t)(65535 - ((uint16_t *)c->pixels)[i * C + 1]);
        else {
            float *g = (float *)c->pixels + i * C + 1;
            *g = is_signed ? -*g : 1.0f - *g;
        }
    }
    return sc_value_new_image(c);
}

/* The `texture` parameter replaces every material's colour texture. */
static int apply_texture_override(const char *texture, const sc_mesh *mesh, loaded *l,
                                  sc_error *err) {
    for (int32_t m = 0; m < mesh->nmat; m++) {
        sc_wrap wu = SC_WRAP_REPEAT, wv = SC_WRAP_REPEAT;
        int found = -1;
        for (int i = 0; i < l->nrefs; i++)
            if (l->refs[i].material == m && l->refs[i].slot == 0) found = i;
        if (found >= 0) {
            texref *r = &l->refs[found];
            wu = r->wrap_u, wv = r->wrap_v;
            free(r->path), free(r->origin);
            r->path = sc_strdup(texture);
            r->origin = sc_strdup("texture");
            r->data = NULL;
            if (!r->path || !r->origin) return sc_fail(err, SC_ENOMEM, "out of memory");
            continue;
        }
        int rc = add_ref(l, m, 0, sc_strdup(texture), NULL, 0, wu, wv, sc_strdup("texture"), err);
        if (rc) return rc;
    }
    return SC_OK;
}

/* ---------------------------------------------------------------- decoding */

typedef struct decode_pool {
    decode_job *jobs;
    int njobs;
    int next;
    pthread_mutex_t lock;
} decode_pool;

static void decode_one(decode_job *j) {
    if (j->rc != SC_OK) return;   /* the file could not be read */
    j->rc = sc_image_decode(j->path ? j->path : "embedded image", j->data, j->size, &j->image, &j->err);
    if (j->rc == SC_OK && j->colorspace == SC_COLOR_DATA) j->image->colorspace = SC_COLOR_DATA;
}

static void *decode_worker(void *ud) {
    decode_pool *pool = ud;
    for (;;) {
        pthread_mutex_lock(&pool->lock);
        int k = pool->next++;
        pthread_mutex_unlock(&pool->lock);
        if (k >= pool->njobs) return NULL;
        decode_one(&pool->jobs[k]);
    }
}

static void decode_all(decode_job *jobs, int njobs, int threads) {
    decode_pool pool = {jobs, njobs, 0, PTHREAD_MUTEX_INITIALIZER};
    if (threads > njobs) threads = njobs;
    pthread_t tid[16];
    if (threads > 16) threads = 16;
    int started = 0;
    for (int i = 1; i < threads; i++)
        if (pthread_create(&tid[started], NULL, decode_worker, &pool) == 0) started++;
    decode_worker(&pool);
    for (int i = 0; i < started; i++) pthread_join(tid[i], NULL);
}

static const char *material_name(const sc_mesh *m, int32_t k) {
    return (k >= 0 && k < m->nmat && m->materials[k]) ? m->materials[k] : "?";
}

/* Read every distinct texture file, then decode them. A colour map that
 * cannot be read or decoded fails the node; any other map (normal,
 * emissive, ...) is optional: it is left out with a warning (r->job = -1). */
static int load_textures(sc_ctx *ctx, loaded *l, sc_error *err) {
    l->jobs = calloc((size_t)l->nrefs + 1, sizeof *l->jobs);
    if (!l->jobs) return sc_fail(err, SC_ENOMEM, "out of memory");
    for (int i = 0; i < l->nrefs; i++) {
        texref *r = &l->refs[i];
        sc_colorspace cs = slot_is_colour(r->slot) ? SC_COLOR_SRGB : SC_COLOR_DATA;
        for (int k = 0; k < l->njobs && r->job < 0; k++) {
            decode_job *j = &l->jobs[k];
            bool same = r->path ? (j->path && strcmp(j->path, r->path) == 0)
                                : (!j->path && j->data == r->data);
            if (same && j->colorspace == cs) r->job = k;
        }
        if (r->job >= 0) continue;
        decode_job *j = &l->jobs[l->njobs];
        j->path = r->path;
        j->colorspace = cs;
        sc_buf_init(&j->bytes);
        if (r->path) {
            j->rc = sc_ctx_read_file(ctx, r->path, MAX_IMAGE_BYTES, &j->bytes, &j->err);
            if (j->rc == SC_ENOMEM) {
                *err = j->err;
                return j->rc;
            }
            j->data = j->bytes.data, j->size = j->bytes.len;
        } else {
            j->data = r->data, j->size = r->size;
        }
        r->job = l->njobs++;
    }
    decode_all(l->jobs, l->njobs, sc_ctx_threads(ctx));
    for (int i = 0; i < l->nrefs; i++) {
        texref *r = &l->refs[i];
        decode_job *j = &l->jobs[r->job];
        if (j->rc == SC_OK) continue;
        if (r->slot == 0 || j->rc == SC_ENOMEM) {
            *err = j->err;
            return sc_error_prefix(err, "%s: material '%s': %s texture", r->origin,
                                   material_name(l->mesh, r->material), slot_names[r->slot]);
        }
        sc_ctx_warn(ctx, "%s: material '%s': %s texture left out: %s", r->origin,
                    material_name(l->mesh, r->material), slot_names[r->slot], j->err.message);
        r->job = -1;
    }
    for (int k = 0; k < l->njobs; k++) {
        decode_job *j = &l->jobs[k];
        sc_buf_free(&j->bytes);
        if (j->rc != SC_OK) continue;
        j->value = sc_value_new_image(j->image);
        j->image = NULL;
        if (!j->value) return sc_fail(err, SC_ENOMEM, "out of memory");
    }
    return SC_OK;
}

/* ---------------------------------------------------------------- edges */

typedef struct edge_counts {
    int64_t edges, boundary, seams, nonmanifold;
} edge_counts;

/* The edge table's counts, seams as meshstats.py counts them: besides the
 * seam edges, a non-manifold edge whose faces do not all use the same uv
 * indices at its ends. */
static int count_edges(const sc_mesh *m, edge_counts *out, sc_error *err) {
    sc_topology t;
    int rc = sc_topology_build(m, NULL, &t, err);
    if (rc != SC_OK) return rc;
    *out = (edge_counts){t.nedges, t.nboundary, t.nseams, t.nnonmanifold};
    for (int32_t i = 0; i < t.nedges; i++) {
        const sc_topology_edge *e = &t.edges[i];
        if (e->kind != SC_EDGE_NONMANIFOLD) continue;
        int32_t h0 = t.half[e->first];
        for (int32_t k = 1; k < e->count; k++) {
            int32_t h = t.half[e->first + k];
            if (sc_topology_uv_at(m, h, e->v0) != sc_topology_uv_at(m, h0, e->v0) ||
                sc_topology_uv_at(m, h, e->v1) != sc_topology_uv_at(m, h0, e->v1)) {
                out->seams++;
                break;
            }
        }
    }
    sc_topology_free(&t);
    return SC_OK;
}

/* ---------------------------------------------------------------- reversed copies */

/* A face's three corner positions, sorted (so that a face and its reversed
 * copy have the same key), and the face. */
typedef struct face_key {
    double pos[9];
    int32_t face;
} face_key;

static int cmp_point(const double *a, const double *b) {
    for (int k = 0; k < 3; k++)
        if (a[k] != b[k]) return a[k] < b[k] ? -1 : 1;
    return 0;
}

static int cmp_points(const face_key *a, const face_key *b) {
    for (int c = 0; c < 3; c++) {
        int r = cmp_point(a->pos + 3 * c, b->pos + 3 * c);
        if (r) return r;
    }
    return 0;
}

static int cmp_face_key(const void *x, const void *y) {
    const face_key *a = x, *b = y;
    int r = cmp_points(a, b);
    return r ? r : (a->face > b->face) - (a->face < b->face);
}

static void face_key_make(const sc_mesh *m, int32_t f, face_key *k) {
    k->face = f;
    for (int c = 0; c < 3; c++) memcpy(k->pos + 3 * c, m->V + 3 * (size_t)m->FV[3 * f + c], 3 * sizeof(double));
    for (int u = 0; u < 3; u++)   /* three points: a sort by exchange */
        for (int v = u + 1; v < 3; v++)
            if (cmp_point(k->pos + 3 * v, k->pos + 3 * u) < 0) {
                double t[3];
                memcpy(t, k->pos + 3 * u, sizeof t);
                memcpy(k->pos + 3 * u, k->pos + 3 * v, sizeof t);
                memcpy(k->pos + 3 * v, t, sizeof t);
            }
}

/* Whether face g is face f reversed: the same points in the other cyclic
 * order, the same material, the same uv at each point. */
static bool reversed_copy(const sc_mesh *m, int32_t f, int32_t g) {
    if (m->FM[f] != m->FM[g]) return false;
    for (int k = 0; k < 3; k++) {
        const double *p = m->V + 3 * (size_t)m->FV[3 * f + k];
        int j = 0;
        while (j < 3 && cmp_point(p, m->V + 3 * (size_t)m->FV[3 * g + j]) != 0) j++;
        if (j == 3) return false;
        /* f's next corner must be g's previous one */
        const double *next_f = m->V + 3 * (size_t)m->FV[3 * f + (k + 1) % 3];
        if (cmp_point(next_f, m->V + 3 * (size_t)m->FV[3 * g + (j + 2) % 3]) != 0) return false;
        const double *uf = m->U + 2 * (size_t)m->FU[3 * f + k], *ug = m->U + 2 * (size_t)m->FU[3 * g + j];
        if (uf[0] != ug[0] || uf[1] != ug[1]) return false;
    }
    return true;
}

/* Drops every face that is an earlier face reversed (a double-sided model
 * made of two copies of its surface: the second has nothing to add once the
 * material draws both sides); their materials are flagged in two_sided
 * (nmat). The mesh is rebuilt compact; *dropped counts the faces. */
static int drop_reversed_copies(sc_mesh **mesh, uint8_t *two_sided, int64_t *dropped, sc_error *err) {
    sc_mesh *m = *mesh;
    *dropped = 0;
    face_key *keys = malloc((size_t)(m->nf > 0 ? m->nf : 1) * sizeof *keys);
    uint8_t *gone = calloc((size_t)m->nf + 1, 1);
    if (!keys || !gone) {
        free(keys), free(gone);
        return sc_fail(err, SC_ENOMEM, "out of memory");
    }
    for (int32_t f = 0; f < m->nf; f++) face_key_make(m, f, &keys[f]);
    qsort(keys, (size_t)m->nf, sizeof *keys, cmp_face_key);
    for (int32_t i = 0; i < m->nf;) {
        int32_t j = i + 1;
        while (j < m->nf && cmp_points(&keys[i], &keys[j]) == 0) j++;
        for (int32_t x = i; x < j; x++)   /* each face paired with one later reversed copy */
            for (int32_t y = x + 1; y < j && !gone[keys[x].face]; y++) {
                int32_t f = keys[x].face, g = keys[y].face;   /* f < g: keys sort by face within a group */
                if (gone[g] || !reversed_copy(m, f, g)) continue;
                gone[g] = 1, two_sided[m->FM[g]] = 1, (*dropped)++;
                break;
            }
        i = j;
    }
    free(keys);
    int rc = SC_OK;
    if (*dropped > 0) {
        int32_t *FV = malloc((size_t)m->nf * 3 * sizeof *FV), *FU = malloc((size_t)m->nf * 3 * sizeof *FU);
        int32_t *FN = m->nn ? malloc((size_t)m->nf * 3 * sizeof *FN) : NULL, *FM = malloc((size_t)m->nf * sizeof *FM);
        int64_t n = 0;
        if (!FV || !FU || !FM || (m->nn && !FN)) rc = sc_fail(err, SC_ENOMEM, "out of memory");
        for (int32_t f = 0; f < m->nf && rc == SC_OK; f++) {
            if (gone[f]) continue;
            memcpy(FV + 3 * n, m->FV + 3 * (size_t)f, 3 * sizeof *FV);
            memcpy(FU + 3 * n, m->FU + 3 * (size_t)f, 3 * sizeof *FU);
            if (FN) memcpy(FN + 3 * n, m->FN + 3 * (size_t)f, 3 * sizeof *FN);
            FM[n++] = m->FM[f];
        }
        sc_mesh *out = NULL;
        int64_t degenerate = 0;
        if (rc == SC_OK)
            rc = sc_mesh_build_compact(m->V, m->nv, m->U, m->nu, m->N, m->nn, FV, FU, FN, FM, n, m->materials, m->nmat,
                                       &out, &degenerate, NULL, err);
        if (rc == SC_OK) sc_mesh_free(m), *mesh = out;
        free(FV), free(FU), free(FN), free(FM);
    }
    free(gone);
    return rc;
}

/* A glTF material whose metallic-roughness or emissive map is not in the
 * atlas (left out, unreadable, or not among `slots`): its factor, which
 * multiplied that map, would stand alone for the whole surface (a fully
 * metallic or glowing one); the material becomes what it is without the
 * map by the conventions the outputs follow (sc_atlas_material): a
 * dielectric, no emission. */
static void constants_without_maps(sc_atlas *a, const sc_gltf *g) {
    for (int32_t i = 0; a->materials && i < g->ntextures; i++) {
        const sc_gltf_texture *t = &g->textures[i];
        if (sc_atlas_find_texture(a, t->material, t->slot) >= 0) continue;
        sc_material *c = &a->materials[t->material];
        if (strcmp(t->slot, "metallic_roughness") == 0) c->metallic = 0;
        if (strcmp(t->slot, "emissive") == 0) c->emissive[0] = c->emissive[1] = c->emissive[2] = 0;
    }
}

/* The materials flagged in two_sided made double-sided; an atlas without
 * constants (an OBJ's) first gets those its outputs follow anyway
 * (sc_atlas_material). */
static int mark_two_sided(sc_atlas *a, const uint8_t *two_sided, sc_error *err) {
    int32_t nmat = a->mesh->as.mesh->nmat;
    if (!a->materials) {
        sc_material *c = malloc((size_t)(nmat > 0 ? nmat : 1) * sizeof *c);
        if (!c) return sc_fail(err, SC_ENOMEM, "out of memory");
        for (int32_t k = 0; k < nmat; k++) c[k] = sc_atlas_material(a, k);
        a->materials = c;
    }
    for (int32_t k = 0; k < nmat; k++)
        if (two_sided[k]) a->materials[k].double_sided = true;
    return SC_OK;
}

/* ---------------------------------------------------------------- the node */

/* A model that cooks without colour, in whole or in part, says so. */
static void warn_untextured(sc_ctx *ctx, const sc_atlas *atlas) {
    const sc_mesh *mesh = atlas->mesh->as.mesh;
    int32_t bare = 0, first = -1;
    for (int32_t m = 0; m < mesh->nmat; m++)
        if (sc_atlas_find_texture(atlas, m, "color") < 0 && bare++ == 0) first = m;
    if (atlas->ntex == 0)
        sc_ctx_warn(ctx, "no texture: the model names none, so it cooks untextured (an OBJ finds its "
                         "textures through the MTL its mtllib line names)");
    else if (bare > 0)
        sc_ctx_warn(ctx, "%d of %d materials have no colour texture (the first: '%s'): their faces cook untextured",
                    (int)bare, (int)mesh->nmat, material_name(mesh, first));
}

static bool has_extension(const char *path, const char *ext) {
    size_t n = strlen(path), e = strlen(ext);
    return n > e && strcasecmp(path + n - e, ext) == 0;
}

static int run(sc_ctx *ctx, sc_error *err) {
    const char *path = sc_ctx_string(ctx, "path");
    const char *texture = sc_ctx_string(ctx, "texture");
    const char *wrap = sc_ctx_string(ctx, "wrap");
    bool wanted[NSLOTS];
    int rc = parse_slots(sc_ctx_string(ctx, "slots"), wanted, err);
    if (rc) return sc_error_prefix(err, "slots");
    bool is_obj = has_extension(path, ".obj");
    bool is_gltf = has_extension(path, ".gltf") || has_extension(path, ".glb");
    if (!is_obj && !is_gltf)
        return sc_fail(err, SC_EINPUT, "path: %s: unknown model format (expected .obj, .gltf or .glb)", path);

    double t0 = sc_now();
    sc_buf bytes;
    sc_buf_init(&bytes);
    if ((rc = sc_ctx_read_file(ctx, path, MAX_MODEL_BYTES, &bytes, err))) return rc;
    char *dir = sc_path_dirname(path);
    const char *root = sc_ctx_string(ctx, "asset_root");
    file_reader fr = {ctx, dir, *root ? root : dir};
    loaded l;
    memset(&l, 0, sizeof l);
    if (!dir) rc = sc_fail(err, SC_ENOMEM, "out of memory");
    else if (is_obj) rc = load_obj(&fr, path, &bytes, wanted, &l, err);
    else rc = load_gltf(&fr, path, &bytes, wanted, &l, err);
    sc_buf_free(&bytes);
    free(dir);
    if (rc == SC_OK && *texture) rc = apply_texture_override(texture, l.mesh, &l, err);
    if (rc == SC_OK) rc = sc_mesh_check(l.mesh, err);
    uint8_t *two_sided = rc == SC_OK ? calloc((size_t)l.mesh->nmat + 1, 1) : NULL;
    int64_t reversed = 0;
    if (rc == SC_OK) rc = two_sided ? drop_reversed_copies(&l.mesh, two_sided, &reversed, err)
                                    : sc_fail(err, SC_ENOMEM, "out of memory");
    double t1 = sc_now();
    if (rc == SC_OK) rc = load_textures(ctx, &l, err);
    double t2 = sc_now();
    edge_counts edges = {0};
    if (rc == SC_OK) rc = count_edges(l.mesh, &edges, err);
    if (rc != SC_OK) {
        loaded_free(&l);
        free(two_sided);
        return rc;
    }

    const sc_mesh *mesh = l.mesh;
    double faces = mesh->nf, vertices = mesh->nv, uvs = mesh->nu, materials = mesh->nmat;
    sc_value *mesh_value = sc_value_new_mesh(l.mesh);
    l.mesh = NULL;
    sc_atlas *atlas = mesh_value ? sc_atlas_new(mesh_value) : NULL;
    if (!atlas) {
        loaded_free(&l);
        return sc_fail(err, SC_ENOMEM, "out of memory");
    }
    if (l.gltf.materials) atlas->materials = l.gltf.materials, l.gltf.materials = NULL;   /* the same materials */
    /* textures in material order, then slot order: the same atlas for any file order */
    int flipped = 0;
    for (int32_t m = 0; m < (int32_t)materials && rc == SC_OK; m++)
        for (int s = 0; s < NSLOTS && rc == SC_OK; s++)
            for (int i = 0; i < l.nrefs && rc == SC_OK; i++) {
                texref *r = &l.refs[i];
                if (r->material != m || r->slot != s || r->job < 0) continue;
                sc_wrap wu = r->wrap_u, wv = r->wrap_v;
                if (strcmp(wrap, "auto") != 0) {
                    wu = wv = strcmp(wrap, "clamp") == 0    ? SC_WRAP_CLAMP
                              : strcmp(wrap, "mirror") == 0 ? SC_WRAP_MIRROR
                                                            : SC_WRAP_REPEAT;
                }
                const char *base = r->path ? strrchr(r->path, '/') : NULL;
                const char *source = r->path ? (base ? base + 1 : r->path) : "";
                sc_value *image = r->green_flipped ? green_flipped_copy(l.jobs[r->job].value->as.image)
                                                   : sc_value_retain(l.jobs[r->job].value);
                flipped += r->green_flipped;
                rc = image ? sc_atlas_add_texture(atlas, slot_names[s], m, wu, wv, source, image)
                           : sc_fail(err, SC_ENOMEM, "out of memory");
                break;   /* one texture per (material, slot) */
            }
    if (rc == SC_OK) constants_without_maps(atlas, &l.gltf);
    if (rc == SC_OK && reversed > 0) rc = mark_two_sided(atlas, two_sided, err);
    free(two_sided);
    if (rc == SC_OK && reversed > 0)
        sc_ctx_warn(ctx, "%lld faces are reversed copies of others (a double-sided model): dropped, their materials "
                         "marked double-sided (a glTF output says so; an OBJ cannot)",
                    (long long)reversed);
    int32_t ntex = atlas->ntex;
    int64_t without_uv = l.obj.faces_without_uv + l.gltf.faces_without_uv;
    if (rc == SC_OK && (l.obj.uv_missing || l.gltf.uv_missing) && ntex > 0)
        rc = ntex == 1 ? sc_fail(err, SC_EINPUT, "path: %s has no texture coordinates, so its texture cannot be mapped",
                                 path)
                       : sc_fail(err, SC_EINPUT, "path: %s has no texture coordinates, so its %d textures cannot be "
                                 "mapped", path, (int)ntex);
    if (rc == SC_OK && without_uv > 0)
        sc_ctx_warn(ctx, "%lld of %lld faces have no texture coordinates: their uv are (0, 0), with no area, until "
                         "quad_chartify (mode auto or always) gives the model an atlas",
                    (long long)without_uv, (long long)faces);
    if (rc == SC_OK) warn_untextured(ctx, atlas);
    sc_value *value = rc == SC_OK ? sc_value_new_atlas(atlas) : NULL;
    if (rc != SC_OK) sc_atlas_free(atlas);
    int64_t degenerate = l.obj.degenerate_faces_dropped + l.gltf.degenerate_faces_dropped;
    loaded_free(&l);
    if (rc != SC_OK) return rc;
    if (!value) return sc_fail(err, SC_ENOMEM, "out of memory");
    sc_ctx_set_output(ctx, "atlas", value);
    sc_ctx_metric(ctx, "faces", faces);
    sc_ctx_metric(ctx, "vertices", vertices);
    sc_ctx_metric(ctx, "uv_vertices", uvs);
    sc_ctx_metric(ctx, "materials", materials);
    sc_ctx_metric(ctx, "normal_maps_green_flipped", flipped);
    sc_ctx_metric(ctx, "textures", ntex);
    sc_ctx_metric(ctx, "seam_edges", (double)edges.seams);
    sc_ctx_metric(ctx, "boundary_edges", (double)edges.boundary);
    sc_ctx_metric(ctx, "nonmanifold_edges", (double)edges.nonmanifold);
    sc_ctx_metric(ctx, "degenerate_faces_dropped", (double)degenerate);
    sc_ctx_metric(ctx, "faces_without_uv", (double)without_uv);
    sc_ctx_metric(ctx, "reversed_copies_dropped", (double)reversed);
    sc_ctx_metric(ctx, "seconds_parse", t1 - t0);
    sc_ctx_metric(ctx, "seconds_decode", t2 - t1);
    return SC_OK;
}

static const char *const wrap_choices[] = {"auto", "repeat", "clamp", "mirror", NULL};

static const sc_param_desc params[] = {
    {.name = "path", .type = SC_PARAM_PATH, .required = true,
     .doc = "the model: .obj (with its MTL), .gltf or .glb"},
    {.name = "texture", .type = SC_PARAM_PATH, .def_string = "",
     .doc = "when given, this image is the colour texture of every material"},
    {.name = "wrap", .type = SC_PARAM_ENUM, .def_string = "auto", .choices = wrap_choices,
     .doc = "texture wrap mode; auto: what the file says (OBJ: repeat, glTF: the sampler)"},
    {.name = "asset_root", .type = SC_PARAM_PATH, .def_string = "",
     .doc = "the folder every file the model names (MTL, textures, glTF buffers and images) must lie in; "
            "empty: the model's own folder (seamcook run --asset-root sets it on every load_atlas)"},
    {.name = "slots", .type = SC_PARAM_STRING, .def_string = "all",
     .doc = "texture slots to load, comma-separated (color, normal, emissive, occlusion, "
            "metallic_roughness), or all",
     .check_text = check_slots},
};

static const sc_port_desc outputs[] = {
    {.name = "atlas", .kind = SC_KIND_ATLAS, .doc = "the mesh and its textures"},
};

static const sc_kernel *const kernels[] = {&sc_kernel_gltf, &sc_kernel_imageio, &sc_kernel_obj, &sc_kernel_topology,
                                            NULL};

const sc_node_desc sc_node_load_atlas = {
    .type = "load_atlas",
    .version = 5,
    .summary = "load a textured mesh (OBJ + MTL, glTF 2.0) and its textures",
    .outputs = outputs,
    .noutputs = SC_COUNT(outputs),
    .params = params,
    .nparams = SC_COUNT(params),
    .run = run,
    .kernels = kernels,
};
