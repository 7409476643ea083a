/* save.c - the node `save`: an atlas, a chain of LODs or an image as files.
 *
 * Design note. save never touches the file system: it encodes everything
 * into memory and returns a REPORT whose files (relative paths -> bytes) the
 * engine writes into --out, so a failed run never leaves half an asset
 * behind. Output bytes depend only on the inputs and parameters: OBJ numbers
 * are printed as the shortest text that reads back to the same double
 * (sc_format_double), so an OBJ written here loads back bit-identical; no
 * dates or versions are written.
 *
 * Files, for name = N:
 *   atlas   N.obj, N.mtl, and one texture file per (material, slot):
 *           N_<material>_<slot>.<ext>
 *   lods    N_lod<k>.obj for every level, all naming N.mtl: one shared
 *           texture set, written once, from the atlas input when connected,
 *           else from level 0 (the levels share one parameterisation)
 *   image   N.<ext>
 *   glb     N.glb (glb = true, with an atlas or lods): glTF 2.0 holding the
 *           atlas's mesh and every level as MSFT_lod levels of one node, the
 *           texture set's PNG/JPEG files embedded (sc_gltf_write_glb); with
 *           gltf_form = gltf, N.gltf and N.bin instead, the JSON naming the
 *           texture files beside it (sc_gltf_write_gltf)
 *   obj = false: no OBJ or MTL, and the texture set's PNG/JPEG files live
 *           only inside the .glb (its images named as the files would be);
 *           float textures, which glTF cannot hold, are still files
 * The MTL names colour maps with map_Kd, normal maps with map_Bump (what
 * Blender and most OBJ readers take for a normal map; load_atlas reads norm,
 * map_Bump and bump), emissive maps with map_Ke; other slots have no MTL
 * statement and are listed in a comment, "# <slot> <file>":
 * metallic_roughness holds glTF's layout (roughness in G, metallic in B),
 * occlusion is glTF's (R). Faces are written in the mesh's
 * order with a usemtl wherever the material changes. Material names are made
 * file-safe ([A-Za-z0-9_.-], others become '_'; duplicates get a suffix). A
 * texture image shared by several (material, slot) pairs is written once.
 *
 * Texture format: auto writes 8/16-bit images as PNG, which holds every
 * byte (a JPEG input too: re-encoding it lossily would undo what erasure
 * and mip-mapping made of it), and float data as EXR; png, jpg and exr force
 * one. exr_too also writes every texture as float EXR beside it.
 *
 * Metrics describe files: every texture file of an atlas or LOD set is
 * decoded from the bytes written, the way a reader does, and its seams are
 * measured on the set's mesh as a renderer filters them (sRGB colour in
 * linear light), beside the image it was encoded from: <file>.seam_energy,
 * .max_seam_gap and .seam_gap_added (how much wider the file's seams are),
 * and their worst over the files. max_seam_gap >= 0 fails the save when a
 * file adds more than that (a JPEG, a clamp, a colour conversion).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sc_gltf.h"
#include "sc_imageio.h"
#include "sc_nodes.h"
#include "sc_seam.h"

/* ---------------------------------------------------------------- text */

static void put_number(sc_buf *b, double v) {
    char text[32];
    sc_format_double(v, text);
    sc_buf_puts(b, text);
}

/* One OBJ line: the keyword and n numbers. */
static void put_row(sc_buf *out, const char *keyword, const double *x, int n) {
    sc_buf_puts(out, keyword);
    for (int k = 0; k < n; k++) {
        sc_buf_puts(out, " ");
        put_number(out, x[k]);
    }
    sc_buf_puts(out, "\n");
}

static void put_int(sc_buf *b, int64_t v) {
    char text[24];
    int n = 0;
    uint64_t u = v < 0 ? (uint64_t)(-(v + 1)) + 1 : (uint64_t)v;
    do {
        text[n++] = (char)('0' + u % 10);
        u /= 10;
    } while (u);
    if (v < 0) text[n++] = '-';
    char out[24];
    for (int i = 0; i < n; i++) out[i] = text[n - 1 - i];
    sc_buf_append(b, out, (size_t)n);
}

/* A file-safe version of a material name. */
static char *safe_name(const char *s) {
    char *out = sc_strdup(*s ? s : "material");
    if (!out) return NULL;
    for (char *c = out; *c; c++) {
        bool ok = (*c >= 'a' && *c <= 'z') || (*c >= 'A' && *c <= 'Z') || (*c >= '0' && *c <= '9') ||
                  *c == '_' || *c == '-' || *c == '.';
        if (!ok) *c = '_';
    }
    return out;
}

/* The `file` parameter: a plain file name (checked when the graph is built). */
static int check_name(const char *name, sc_error *err) {
    if (!*name) return sc_fail(err, SC_EINPUT, "must not be empty");
    if (strcmp(name, ".") == 0 || strcmp(name, "..") == 0)
        return sc_fail(err, SC_EINPUT, "'%s' is not a file name", name);
    for (const char *c = name; *c; c++) {
        bool ok = (*c >= 'a' && *c <= 'z') || (*c >= 'A' && *c <= 'Z') || (*c >= '0' && *c <= '9') ||
                  *c == '_' || *c == '-' || *c == '.';
        if (!ok)
            return sc_fail(err, SC_EINPUT, "'%s' is not a plain file name (letters, digits, '_', '-', '.')", name);
    }
    return SC_OK;
}

/* Material names for the files: safe and distinct. */
static char **material_names(const sc_mesh *m) {
    char **names = sc_calloc_array((size_t)m->nmat, sizeof(char *));
    if (!names) return NULL;
    for (int32_t k = 0; k < m->nmat; k++) {
        char *s = safe_name(m->materials[k] ? m->materials[k] : "");
        for (int32_t j = 0; s && j < k; j++)
            if (strcmp(names[j], s) == 0) {
                char *t = sc_strprintf("%s_%d", s, k);
                free(s);
                s = t;
                j = -1;
            }
        if (!s) {
            for (int32_t j = 0; j < k; j++) free(names[j]);
            free(names);
            return NULL;
        }
        names[k] = s;
    }
    return names;
}

static void free_names(char **names, int32_t n) {
    if (!names) return;
    for (int32_t k = 0; k < n; k++) free(names[k]);
    free(names);
}

/* The OBJ text of a mesh. Material names are looked up by the mesh's own
 * names in the texture set's (so LOD levels use the MTL's names). */
static int write_obj(const sc_mesh *m, const sc_mesh *set, char *const *set_names, const char *mtl,
                     sc_buf *out, sc_error *err) {
    int32_t *usemtl = sc_alloc_array((size_t)m->nmat, sizeof(int32_t));
    if (!usemtl) return sc_fail(err, SC_ENOMEM, "out of memory");
    for (int32_t k = 0; k < m->nmat; k++) {
        usemtl[k] = -1;
        for (int32_t j = 0; j < set->nmat; j++)
            if (strcmp(m->materials[k], set->materials[j]) == 0) usemtl[k] = j;
        if (usemtl[k] < 0) {
            free(usemtl);
            return sc_fail(err, SC_EINPUT, "material '%s' is not in the texture set", m->materials[k]);
        }
    }
    sc_buf_puts(out, "# seamcook\nmtllib ");
    sc_buf_puts(out, mtl);
    sc_buf_puts(out, "\n");
    for (int32_t i = 0; i < m->nv; i++) put_row(out, "v", m->V + 3 * i, 3);
    for (int32_t i = 0; i < m->nu; i++) put_row(out, "vt", m->U + 2 * i, 2);
    for (int32_t i = 0; i < m->nn; i++) put_row(out, "vn", m->N + 3 * i, 3);
    int32_t current = -1;
    for (int32_t f = 0; f < m->nf; f++) {
        if (m->FM[f] != current) {
            current = m->FM[f];
            sc_buf_puts(out, "usemtl ");
            sc_buf_puts(out, set_names[usemtl[current]]);
            sc_buf_puts(out, "\n");
        }
        sc_buf_puts(out, "f");
        for (int k = 0; k < 3; k++) {
            sc_buf_puts(out, " ");
            put_int(out, (int64_t)m->FV[3 * f + k] + 1);
            sc_buf_puts(out, "/");
            put_int(out, (int64_t)m->FU[3 * f + k] + 1);
            if (m->nn) {
                sc_buf_puts(out, "/");
                put_int(out, (int64_t)m->FN[3 * f + k] + 1);
            }
        }
        sc_buf_puts(out, "\n");
    }
    free(usemtl);
    if (out->failed) return sc_fail(err, SC_ENOMEM, "out of memory");
    return SC_OK;
}

/* ---------------------------------------------------------------- files */

static int add_file(sc_report *r, const char *path, sc_buf *b, sc_error *err) {
    if (b->failed) return sc_fail(err, SC_ENOMEM, "%s: out of memory", path);
    void *data = b->data ? b->data : malloc(1);
    size_t size = b->len;
    memset(b, 0, sizeof *b);
    if (!data || sc_report_add_file(r, path, data, size) != SC_OK)
        return sc_fail(err, SC_ENOMEM, "%s: out of memory", path);
    return SC_OK;
}

/* The extension a texture is written with under `format`. */
static const char *texture_ext(const sc_image_data *im, const char *format) {
    if (strcmp(format, "auto") != 0) return format;
    return im->pixel == SC_PIXEL_F32 ? "exr" : "png";
}

static int encode(const sc_value *image, const char *ext, sc_buf *out, sc_error *err) {
    const sc_image_data *im = image->as.image;
    if (strcmp(ext, "png") == 0) return sc_image_value_encode_png(image, 0, out, err);
    if (strcmp(ext, "jpg") == 0) return sc_image_encode_jpeg(im, 95, out, err);
    return sc_image_encode_exr(im, out, err);
}

/* One encoded texture file, so a shared image is encoded once: in the
 * report when it is written as a file, else its bytes kept here for the
 * .glb. */
typedef struct written {
    sc_digest digest;
    char ext[8];
    char *path;
    sc_buf kept;
    const uint8_t *data;   /* its bytes: the report's file, or kept */
    size_t size;
} written;

typedef struct saver {
    sc_ctx *ctx;
    sc_report *report;
    const char *name, *format;
    bool exr_too;
    bool obj;                 /* OBJ and MTL files */
    bool separate;            /* gltf_form gltf: .gltf + .bin naming texture files */
    bool texture_files;       /* textures as files (obj, or gltf_form gltf); else only inside the .glb */
    double max_seam_gap;      /* a file whose decoded seams open wider than its image's, by more, fails */
    written *files;
    int nfiles;
    int64_t bytes;
    double worst_energy, worst_gap, worst_added_gap;   /* over the texture files, as decoded */
    sc_gltf_out_texture *glb_tex;   /* the texture set's PNG/JPEG files, for the .glb (paths in glb_path) */
    const char **glb_path;
    int nglb;
} saver;

/* Where a texture's seams are measured: its mesh, its material's seams
 * (found once per material), its wrap modes. */
typedef struct seam_place {
    const sc_mesh *mesh;
    const sc_seam_set *seams;
    const sc_texture *tex;
} seam_place;

/* The seam energy and largest gap of an image as its consumer filters it:
 * sRGB colour decoded to linear light, anything else as stored. */
static int seen_seams(const seam_place *at, const sc_seam_set *seams, const sc_image_data *im, double *energy,
                      double *gap, sc_error *err) {
    sc_seam_grid g = {im->width, im->height, at->tex->wrap_u, at->tex->wrap_v};
    const bool decode = true;   /* sRGB images only */
    return sc_seam_energies_decoded(at->mesh, seams, &g, &im, &decode, 1, 1, energy, gap, err);
}

/* Metrics describe files: the file's bytes decoded the way a reader does,
 * then its seams measured as filtered, beside the image it was encoded
 * from. <file>.seam_energy and .max_seam_gap; .seam_gap_added: how much
 * wider the file's seams are than the image's (a lossy format, a clamp or
 * a colour conversion), which fails the save beyond max_seam_gap. */
static int measure_file(saver *s, const seam_place *at, const sc_image_data *im, const char *file,
                        const sc_buf *bytes, sc_error *err) {
    sc_image_data *decoded = NULL;
    double e_file = 0, g_file = 0, e_mem = 0, g_mem = 0;
    int rc = sc_image_decode(file, bytes->data, bytes->len, &decoded, err);
    /* a PNG does not say whether it holds colour or data: the material slot
     * does, and a renderer reads a data map (a normal map) as stored, not as
     * the sRGB colour an 8-bit PNG is otherwise decoded as */
    if (rc == SC_OK && im->colorspace == SC_COLOR_DATA) decoded->colorspace = SC_COLOR_DATA;
    if (rc == SC_OK) rc = seen_seams(at, at->seams, decoded, &e_file, &g_file, err);
    if (rc == SC_OK) rc = seen_seams(at, at->seams, im, &e_mem, &g_mem, err);
    sc_image_free(decoded);
    if (rc) return rc;
    double added = g_file > g_mem ? g_file - g_mem : 0;
    char name[512];
    const char *keys[3] = {"seam_energy", "max_seam_gap", "seam_gap_added"};
    const double vals[3] = {e_file, g_file, added};
    for (int k = 0; k < 3; k++) {
        snprintf(name, sizeof name, "%s.%s", file, keys[k]);
        if (sc_report_metric(s->report, name, vals[k])) return sc_fail(err, SC_ENOMEM, "out of memory");
        sc_ctx_metric(s->ctx, name, vals[k]);
    }
    s->worst_energy = fmax(s->worst_energy, e_file), s->worst_gap = fmax(s->worst_gap, g_file);
    s->worst_added_gap = fmax(s->worst_added_gap, added);
    if (s->max_seam_gap >= 0 && added > s->max_seam_gap)
        return sc_fail(err, SC_EINPUT,
                       "%s: its seams, decoded as a renderer filters them, open %.3g wider than the image's "
                       "(gap %.3g against %.3g), over max_seam_gap %g: a lossy format or a conversion",
                       file, added, g_file, g_mem, s->max_seam_gap);
    return SC_OK;
}

/* Write image under `path_base`.<ext> (and .exr with exr_too), unless the
 * same image was written already; *path receives the file name used. */
static int save_image(saver *s, const sc_value *image, const seam_place *at, const char *path_base,
                      const char **path, sc_error *err) {
    const sc_image_data *im = image->as.image;
    const char *ext = texture_ext(im, s->format);
    const char *exts[2] = {ext, (s->exr_too && strcmp(ext, "exr") != 0) ? "exr" : NULL};
    for (int e = 0; e < 2 && exts[e]; e++) {
        int found = -1;
        for (int i = 0; i < s->nfiles; i++)
            if (sc_digest_equal(&s->files[i].digest, sc_value_digest(image)) && strcmp(s->files[i].ext, exts[e]) == 0)
                found = i;
        if (found >= 0) {
            if (e == 0) *path = s->files[found].path;
            continue;
        }
        char *file = sc_strprintf("%s.%s", path_base, exts[e]);
        written *w = realloc(s->files, sizeof *w * (size_t)(s->nfiles + 1));
        if (!file || !w) {
            free(file);
            if (w) s->files = w;
            return sc_fail(err, SC_ENOMEM, "out of memory");
        }
        s->files = w;
        sc_buf b;
        sc_buf_init(&b);
        int rc = encode(image, exts[e], &b, err);
        if (rc == SC_OK && at) rc = measure_file(s, at, im, file, &b, err);
        /* a texture only the .glb holds is kept for it; an EXR, which no
         * .glb holds, is always a file */
        bool as_file = !at || s->texture_files || strcmp(exts[e], "exr") == 0;
        if (rc == SC_OK && as_file) {
            s->bytes += (int64_t)b.len;
            rc = add_file(s->report, file, &b, err);
        } else if (rc != SC_OK && !strstr(err->message, file)) {
            sc_error_prefix(err, "%s", file);
        }
        if (rc) {
            sc_buf_free(&b);
            free(file);
            return rc;
        }
        w = &s->files[s->nfiles++];
        w->kept = b;   /* empty when the report took the bytes */
        if (as_file) {
            const sc_bytes *in_report = s->report->files[s->report->nfiles - 1].bytes->as.bytes;
            w->data = in_report->data, w->size = in_report->size;
        } else {
            w->data = (const uint8_t *)w->kept.data, w->size = w->kept.len;
        }
        w->digest = *sc_value_digest(image);
        snprintf(w->ext, sizeof w->ext, "%s", exts[e]);
        w->path = file;
        if (e == 0) *path = file;
    }
    return SC_OK;
}

static const char *mtl_statement(const char *slot) {
    if (strcmp(slot, "color") == 0) return "map_Kd";
    if (strcmp(slot, "normal") == 0) return "map_Bump";
    if (strcmp(slot, "emissive") == 0) return "map_Ke";
    return NULL;
}

/* The texture files and the MTL of a texture set. */
static int save_texture_set(saver *s, const sc_atlas *set, char *const *names, sc_error *err) {
    const sc_mesh *m = set->mesh->as.mesh;
    sc_buf mtl;
    sc_buf_init(&mtl);
    sc_buf_puts(&mtl, "# seamcook\n");
    int rc = SC_OK;
    for (int32_t k = 0; k < m->nmat && rc == SC_OK; k++) {
        const sc_material c = sc_atlas_material(set, k);   /* Kd and d multiply map_Kd */
        sc_buf_printf(&mtl, "\nnewmtl %s\nKd %.17g %.17g %.17g\n", names[k], c.base_color[0], c.base_color[1],
                      c.base_color[2]);
        if (c.base_color[3] != 1) sc_buf_printf(&mtl, "d %.17g\n", c.base_color[3]);
        sc_seam_set seams = {0};
        bool found = false;
        for (int32_t t = 0; t < set->ntex && rc == SC_OK; t++) {
            const sc_texture *tex = &set->textures[t];
            if (tex->material != k) continue;
            char *slot = safe_name(tex->name);
            char *base = slot ? sc_strprintf("%s_%s_%s", s->name, names[k], slot) : NULL;
            const char *file = NULL;
            if (!base) rc = sc_fail(err, SC_ENOMEM, "out of memory");
            if (rc == SC_OK && !found) rc = sc_seam_find(m, k, &seams, err), found = rc == SC_OK;
            seam_place at = {m, &seams, tex};
            if (rc == SC_OK) rc = save_image(s, tex->image, &at, base, &file, err);
            const char *ext = file ? strrchr(file, '.') : NULL;
            bool embeddable = ext && (strcmp(ext, ".png") == 0 || strcmp(ext, ".jpg") == 0);
            if (rc == SC_OK && embeddable) {
                sc_gltf_out_texture *gt = realloc(s->glb_tex, sizeof *gt * (size_t)(s->nglb + 1));
                if (gt) s->glb_tex = gt;
                const char **gp = gt ? realloc(s->glb_path, sizeof *gp * (size_t)(s->nglb + 1)) : NULL;
                if (gp) s->glb_path = gp;
                if (!gp) rc = sc_fail(err, SC_ENOMEM, "out of memory");
                else {
                    s->glb_tex[s->nglb] = (sc_gltf_out_texture){k, tex->name, tex->wrap_u, tex->wrap_v, NULL, 0,
                                                                 strcmp(ext, ".png") == 0 ? "image/png" : "image/jpeg"};
                    s->glb_path[s->nglb++] = file;
                }
            }
            if (rc == SC_OK) {
                const char *statement = mtl_statement(tex->name);
                if (statement) sc_buf_printf(&mtl, "%s %s\n", statement, file);
                else sc_buf_printf(&mtl, "# %s %s\n", slot, file);
            }
            free(slot), free(base);
        }
        if (found) sc_seam_set_free(&seams);
    }
    char *path = rc == SC_OK && s->obj ? sc_strprintf("%s.mtl", s->name) : NULL;
    if (rc == SC_OK && s->obj && !path) rc = sc_fail(err, SC_ENOMEM, "out of memory");
    if (rc == SC_OK && s->obj) rc = add_file(s->report, path, &mtl, err);
    free(path);
    sc_buf_free(&mtl);
    return rc;
}

static int save_obj(saver *s, const sc_mesh *m, const sc_mesh *set, char *const *names,
                    const char *file, sc_error *err) {
    sc_buf b;
    sc_buf_init(&b);
    char *mtl = sc_strprintf("%s.mtl", s->name);
    int rc = mtl ? write_obj(m, set, names, mtl, &b, err) : sc_fail(err, SC_ENOMEM, "out of memory");
    if (rc == SC_OK) {
        s->bytes += (int64_t)b.len;
        rc = add_file(s->report, file, &b, err);
    } else {
        sc_error_prefix(err, "%s", file);
    }
    free(mtl);
    sc_buf_free(&b);
    return rc;
}

/* <name>.glb: the atlas's mesh (when given) and every level of detail, finest
 * first, as MSFT_lod levels of one node, with the texture set's PNG/JPEG
 * files embedded (float textures cannot be: glTF holds PNG and JPEG). */
static int save_glb(saver *s, const sc_atlas *atlas, const sc_lods *lods, sc_error *err) {
    int32_t n = (atlas ? 1 : 0) + (lods ? lods->count : 0);
    const sc_atlas *set = atlas ? atlas : lods->levels[0]->as.atlas;
    int32_t nmat = set->mesh->as.mesh->nmat;
    const sc_mesh **levels = calloc((size_t)n, sizeof *levels);
    sc_material *constants = malloc((size_t)(nmat > 0 ? nmat : 1) * sizeof *constants);
    if (!levels || !constants) {
        free(levels), free(constants);
        return sc_fail(err, SC_ENOMEM, "out of memory");
    }
    for (int32_t k = 0; k < nmat; k++) constants[k] = sc_atlas_material(set, k);
    int32_t k = 0;
    if (atlas) levels[k++] = atlas->mesh->as.mesh;
    for (int32_t l = 0; lods && l < lods->count; l++) levels[k++] = lods->levels[l]->as.atlas->mesh->as.mesh;
    for (int i = 0; i < s->nglb; i++) {
        for (int w = 0; w < s->nfiles; w++)
            if (s->files[w].path == s->glb_path[i])
                s->glb_tex[i].bytes = s->files[w].data, s->glb_tex[i].size = s->files[w].size;
        s->glb_tex[i].uri = s->glb_path[i];
    }
    const bool separate = s->separate;
    sc_buf b, bin;
    sc_buf_init(&b), sc_buf_init(&bin);
    char *file = sc_strprintf("%s.%s", s->name, separate ? "gltf" : "glb");
    char *bin_file = separate ? sc_strprintf("%s.bin", s->name) : NULL;
    int rc = !file || (separate && !bin_file) ? sc_fail(err, SC_ENOMEM, "out of memory")
             : separate ? sc_gltf_write_gltf(levels, n, s->glb_tex, s->nglb, constants, bin_file, &b, &bin, err)
                        : sc_gltf_write_glb(levels, n, s->glb_tex, s->nglb, constants, &b, err);
    if (rc == SC_OK) {
        s->bytes += (int64_t)(b.len + bin.len);
        rc = add_file(s->report, file, &b, err);
    }
    if (rc == SC_OK && separate) rc = add_file(s->report, bin_file, &bin, err);
    if (rc) sc_error_prefix(err, "%s.%s", s->name, separate ? "gltf" : "glb");
    free(file), free(bin_file), free(levels), free(constants);
    sc_buf_free(&b), sc_buf_free(&bin);
    return rc;
}

static int run(sc_ctx *ctx, sc_error *err) {
    const sc_atlas *atlas = sc_ctx_atlas(ctx, "atlas");
    const sc_lods *lods = sc_ctx_lods(ctx, "lods");
    const sc_value *image = sc_ctx_input(ctx, "image");
    const bool glb = sc_ctx_bool(ctx, "glb");
    saver s = {.ctx = ctx, .name = sc_ctx_string(ctx, "file"), .format = sc_ctx_string(ctx, "format"),
               .exr_too = sc_ctx_bool(ctx, "exr_too"), .obj = sc_ctx_bool(ctx, "obj"),
               .separate = strcmp(sc_ctx_string(ctx, "gltf_form"), "gltf") == 0,
               .max_seam_gap = sc_ctx_number(ctx, "max_seam_gap")};
    s.texture_files = s.obj || !glb || s.separate;
    int rc = check_name(s.name, err);
    if (rc) return sc_error_prefix(err, "file");
    if (!atlas && !lods && !image)
        return sc_fail(err, SC_EINPUT, "nothing to save: connect atlas, lods or image");
    if ((atlas || lods) && !s.obj && !glb)
        return sc_fail(err, SC_EINPUT, "obj: with glb = false too, nothing would hold the mesh");
    if (lods && lods->count < 1) return sc_fail(err, SC_EINPUT, "lods: no levels");
    if (image && image->kind != SC_KIND_IMAGE) return sc_fail(err, SC_EINPUT, "image: not an image");
    s.report = sc_report_new();
    if (!s.report) return sc_fail(err, SC_ENOMEM, "out of memory");

    const sc_atlas *set = atlas ? atlas : lods ? lods->levels[0]->as.atlas : NULL;
    char **names = NULL;
    if (set) {
        const sc_mesh *set_mesh = set->mesh->as.mesh;
        names = material_names(set_mesh);
        if (!names) rc = sc_fail(err, SC_ENOMEM, "out of memory");
        if (rc == SC_OK) rc = save_texture_set(&s, set, names, err);
        if (rc == SC_OK && atlas && s.obj) {
            char *file = sc_strprintf("%s.obj", s.name);
            rc = file ? save_obj(&s, atlas->mesh->as.mesh, set_mesh, names, file, err)
                      : sc_fail(err, SC_ENOMEM, "out of memory");
            if (rc) sc_error_prefix(err, "atlas");
            free(file);
        }
        for (int32_t k = 0; s.obj && lods && k < lods->count && rc == SC_OK; k++) {
            char *file = sc_strprintf("%s_lod%d.obj", s.name, k);
            rc = file ? save_obj(&s, lods->levels[k]->as.atlas->mesh->as.mesh, set_mesh, names, file, err)
                      : sc_fail(err, SC_ENOMEM, "out of memory");
            if (rc) sc_error_prefix(err, "lods: level %d", k);
            free(file);
        }
        if (rc == SC_OK && glb) rc = save_glb(&s, atlas, lods, err);
        free_names(names, set_mesh->nmat);
    }
    if (rc == SC_OK && image) {
        const char *file = NULL;
        rc = save_image(&s, image, NULL, s.name, &file, err);
        if (rc) sc_error_prefix(err, "image");
    }
    int nfiles = s.report->nfiles;
    for (int i = 0; i < s.nfiles; i++) free(s.files[i].path), sc_buf_free(&s.files[i].kept);
    free(s.files), free(s.glb_tex), free(s.glb_path);
    if (rc == SC_OK) {
        rc = sc_report_metric(s.report, "files", nfiles) || sc_report_metric(s.report, "bytes", (double)s.bytes) ||
                     (set && (sc_report_metric(s.report, "seam_energy", s.worst_energy) ||
                              sc_report_metric(s.report, "max_seam_gap", s.worst_gap) ||
                              sc_report_metric(s.report, "seam_gap_added", s.worst_added_gap)))
                 ? sc_fail(err, SC_ENOMEM, "out of memory")
                 : SC_OK;
    }
    if (rc != SC_OK) {
        sc_report_free(s.report);
        return rc;
    }
    sc_value *v = sc_value_new_report(s.report);
    if (!v) return sc_fail(err, SC_ENOMEM, "out of memory");
    sc_ctx_set_output(ctx, "files", v);
    sc_ctx_metric(ctx, "files", nfiles);
    sc_ctx_metric(ctx, "bytes", (double)s.bytes);
    if (set) {
        sc_ctx_metric(ctx, "seam_energy", s.worst_energy);
        sc_ctx_metric(ctx, "max_seam_gap", s.worst_gap);
        sc_ctx_metric(ctx, "seam_gap_added", s.worst_added_gap);
    }
    return SC_OK;
}

static const char *const format_choices[] = {"auto", "png", "jpg", "exr", NULL};
static const char *const gltf_form_choices[] = {"glb", "gltf", NULL};

static const sc_param_desc params[] = {
    {.name = "file", .type = SC_PARAM_STRING, .def_string = "asset",
     .doc = "base file name of everything written", .check_text = check_name},
    {.name = "format", .type = SC_PARAM_ENUM, .def_string = "auto", .choices = format_choices,
     .doc = "texture format; auto: png for 8/16-bit images (lossless, a JPEG input too), exr for float; "
            "jpg only when asked"},
    {.name = "obj", .type = SC_PARAM_BOOL, .def = 1,
     .doc = "write <file>.obj (with lods, <file>_lod<k>.obj), <file>.mtl and the texture files they name; "
            "false: the .glb alone holds the meshes and its PNG/JPEG textures (float ones are still files)"},
    {.name = "exr_too", .type = SC_PARAM_BOOL, .def = 0,
     .doc = "also write every texture as float EXR"},
    {.name = "glb", .type = SC_PARAM_BOOL, .def = 1,
     .doc = "also write <file>.glb: glTF 2.0 with every level (MSFT_lod) and the PNG/JPEG textures embedded"},
    {.name = "gltf_form", .type = SC_PARAM_ENUM, .def_string = "glb", .choices = gltf_form_choices,
     .doc = "glb: one binary file, textures embedded; gltf: <file>.gltf and <file>.bin, naming the texture "
            "files beside them"},
    {.name = "max_seam_gap", .type = SC_PARAM_NUMBER, .def = -1, .min = -1, .max = 1e30,
     .doc = "fail when a texture file, decoded and filtered as a renderer does (sRGB colour in linear light), "
            "has seams wider than its image's by more than this; -1: measure only"},
};

static const sc_port_desc inputs[] = {
    {.name = "atlas", .kind = SC_KIND_ATLAS, .optional = true, .doc = "a textured mesh"},
    {.name = "lods", .kind = SC_KIND_LODS, .optional = true,
     .doc = "levels of detail sharing one texture set"},
    {.name = "image", .kind = SC_KIND_IMAGE, .optional = true, .doc = "an image on its own"},
};

static const sc_port_desc outputs[] = {
    {.name = "files", .kind = SC_KIND_REPORT, .doc = "the files, for the engine to write into --out"},
};

static const sc_kernel *const kernels[] = {&sc_kernel_imageio, &sc_kernel_seam, &sc_kernel_gltf, NULL};

const sc_node_desc sc_node_save = {
    .type = "save",
    .version = 8,
    .summary = "write an atlas, LODs or an image as OBJ/MTL and PNG/JPEG/EXR files",
    .inputs = inputs,
    .ninputs = SC_COUNT(inputs),
    .outputs = outputs,
    .noutputs = SC_COUNT(outputs),
    .params = params,
    .nparams = SC_COUNT(params),
    .run = run,
    .kernels = kernels,
};
