/* sc_gltf_write.c - glTF 2.0 with every level of detail, as one binary
 * .glb or as a .gltf with its .bin and images beside it (sc_gltf.h). The JSON is printed by hand in a fixed order, numbers as the
 * shortest text that reads back to the same float, so the bytes depend on
 * the inputs alone. Levels go on node 0 through MSFT_lod. Every level has
 * normals (the mesh's, or the smooth ones sc_tangent gives a mesh without)
 * and, when a material has a normal map, the MikkTSpace tangents the erase
 * kernel converted that map with (sc_tangent.h), so a renderer rebuilds the
 * same frames. A level's corners become glTF vertices by their position and
 * uv indices and their normal and tangent values.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sc_gltf.h"
#include "sc_tangent.h"

enum { GL_FLOAT_T = 5126, GL_UINT_T = 5125, GL_ARRAY_BUFFER_T = 34962, GL_ELEMENT_ARRAY_BUFFER_T = 34963 };

typedef struct corner_key {
    int32_t v, u, order;
    float frame[7];   /* normal, then tangent (xyz, w), as written */
} corner_key;

static int cmp_corner(const void *a, const void *b) {
    const corner_key *x = a, *y = b;
    if (x->v != y->v) return x->v < y->v ? -1 : 1;
    if (x->u != y->u) return x->u < y->u ? -1 : 1;
    int c = memcmp(x->frame, y->frame, sizeof x->frame);
    if (c) return c;
    return x->order < y->order ? -1 : x->order > y->order;
}

static bool same_vertex(const corner_key *x, const corner_key *y) {
    return x->v == y->v && x->u == y->u && !memcmp(x->frame, y->frame, sizeof x->frame);
}

/* The JSON being printed and the binary chunk beside it. */
typedef struct glb {
    sc_buf json, bin;
    sc_buf views, accessors;     /* the JSON array bodies, built as we go */
    int32_t nviews, naccessors;
} glb;

static void put_float(sc_buf *b, float v) {
    char text[32];
    for (int digits = 6; digits <= 9; digits++) {
        snprintf(text, sizeof text, "%.*g", digits, (double)v);
        if ((float)strtod(text, NULL) == v) break;
    }
    sc_buf_puts(b, text);
}

/* Append bytes to the binary chunk (4-byte aligned) as a new bufferView. */
static int32_t add_view(glb *g, const void *data, size_t size, int target) {
    while (g->bin.len % 4) sc_buf_u8(&g->bin, 0);
    size_t offset = g->bin.len;
    sc_buf_append(&g->bin, data, size);
    sc_buf_printf(&g->views, "%s{\"buffer\":0,\"byteOffset\":%zu,\"byteLength\":%zu", g->nviews ? "," : "", offset,
                  size);
    if (target) sc_buf_printf(&g->views, ",\"target\":%d", target);
    sc_buf_puts(&g->views, "}");
    return g->nviews++;
}

/* A float accessor of `count` elements of `comps` components, with min/max when asked. */
static int32_t add_float_accessor(glb *g, const float *data, int32_t count, int comps, bool bounds) {
    int32_t view = add_view(g, data, (size_t)count * comps * sizeof(float), GL_ARRAY_BUFFER_T);
    static const char *const types[5] = {"", "SCALAR", "VEC2", "VEC3", "VEC4"};
    sc_buf_printf(&g->accessors, "%s{\"bufferView\":%d,\"componentType\":%d,\"count\":%d,\"type\":\"%s\"",
                  g->naccessors ? "," : "", view, GL_FLOAT_T, count, types[comps]);
    if (bounds && count > 0) {
        for (int pass = 0; pass < 2; pass++) {
            sc_buf_puts(&g->accessors, pass ? ",\"max\":[" : ",\"min\":[");
            for (int c = 0; c < comps; c++) {
                float e = data[c];
                for (int32_t i = 1; i < count; i++) e = pass ? fmaxf(e, data[i * comps + c]) : fminf(e, data[i * comps + c]);
                if (c) sc_buf_puts(&g->accessors, ",");
                put_float(&g->accessors, e);
            }
            sc_buf_puts(&g->accessors, "]");
        }
    }
    sc_buf_puts(&g->accessors, "}");
    return g->naccessors++;
}

static int32_t add_index_accessor(glb *g, const uint32_t *data, int32_t count) {
    int32_t view = add_view(g, data, (size_t)count * sizeof(uint32_t), GL_ELEMENT_ARRAY_BUFFER_T);
    sc_buf_printf(&g->accessors, "%s{\"bufferView\":%d,\"componentType\":%d,\"count\":%d,\"type\":\"SCALAR\"}",
                  g->naccessors ? "," : "", view, GL_UINT_T, count);
    return g->naccessors++;
}

/* One primitive: the faces of material `mat` of mesh m, corners welded by
 * their position and uv indices and frame values (f: the level's frames;
 * tangents written when `tangents`). Prints the primitive's JSON into
 * `prims`. */
static int add_primitive(glb *g, const sc_mesh *m, const sc_tangent_frames *fr, bool tangents, int32_t mat,
                         bool *first, sc_buf *prims, sc_error *err) {
    int32_t nf = 0;
    for (int32_t f = 0; f < m->nf; f++) nf += m->FM[f] == mat;
    if (nf == 0) return SC_OK;
    int32_t nc = 3 * nf;
    corner_key *keys = malloc((size_t)nc * sizeof *keys);
    uint32_t *index = malloc((size_t)nc * sizeof *index);
    float *pos = malloc((size_t)nc * 3 * sizeof *pos), *uv = malloc((size_t)nc * 2 * sizeof *uv);
    float *nrm = malloc((size_t)nc * 3 * sizeof *nrm), *tan = malloc((size_t)nc * 4 * sizeof *tan);
    int32_t *first_of = malloc((size_t)nc * sizeof *first_of), *vid = malloc((size_t)nc * sizeof *vid);
    if (!keys || !index || !pos || !uv || !nrm || !tan || !first_of || !vid) {
        free(keys), free(index), free(pos), free(uv), free(nrm), free(tan), free(first_of), free(vid);
        return sc_fail(err, SC_ENOMEM, "glb: out of memory");
    }
    int32_t k = 0;
    for (int32_t f = 0; f < m->nf; f++) {
        if (m->FM[f] != mat) continue;
        for (int c = 0; c < 3; c++, k++) {
            size_t at = 3 * (size_t)f + c;
            keys[k] = (corner_key){m->FV[at], m->FU[at], k, {0}};
            for (int d = 0; d < 3; d++) keys[k].frame[d] = (float)fr->normal[3 * at + d];
            for (int d = 0; d < 4 && tangents; d++) keys[k].frame[3 + d] = (float)fr->tangent[4 * at + d];
        }
    }
    qsort(keys, (size_t)nc, sizeof *keys, cmp_corner);
    /* vertices numbered by first appearance in face order */
    for (int32_t i = 0; i < nc;) {
        int32_t j = i;
        while (j < nc && same_vertex(&keys[j], &keys[i])) j++;
        for (int32_t t = i; t < j; t++) first_of[keys[t].order] = keys[i].order;   /* the group's earliest corner */
        i = j;
    }
    int32_t nv = 0;
    for (int32_t c = 0; c < nc; c++) {
        if (first_of[c] == c) vid[c] = nv++;
        index[c] = (uint32_t)vid[first_of[c]];
    }
    k = 0;
    for (int32_t f = 0; f < m->nf; f++) {
        if (m->FM[f] != mat) continue;
        for (int c = 0; c < 3; c++, k++) {
            if (first_of[k] != k) continue;
            int32_t o = vid[k];
            size_t at = 3 * (size_t)f + c;
            const double *V = m->V + 3 * (size_t)m->FV[at], *U = m->U + 2 * (size_t)m->FU[at];
            for (int d = 0; d < 3; d++) pos[3 * o + d] = (float)V[d];
            uv[2 * o] = (float)U[0], uv[2 * o + 1] = (float)(1.0 - U[1]);
            for (int d = 0; d < 3; d++) nrm[3 * o + d] = (float)fr->normal[3 * at + d];
            for (int d = 0; d < 4; d++) tan[4 * o + d] = (float)fr->tangent[4 * at + d];
        }
    }
    int32_t ap = add_float_accessor(g, pos, nv, 3, true);
    int32_t at = add_float_accessor(g, uv, nv, 2, false);
    int32_t an = add_float_accessor(g, nrm, nv, 3, false);
    int32_t atan = tangents ? add_float_accessor(g, tan, nv, 4, false) : -1;
    int32_t ai = add_index_accessor(g, index, nc);
    sc_buf_printf(prims, "%s{\"attributes\":{\"POSITION\":%d,\"TEXCOORD_0\":%d,\"NORMAL\":%d", *first ? "" : ",", ap,
                  at, an);
    if (atan >= 0) sc_buf_printf(prims, ",\"TANGENT\":%d", atan);
    sc_buf_printf(prims, "},\"indices\":%d,\"material\":%d,\"mode\":4}", ai, mat);
    *first = false;
    free(keys), free(index), free(pos), free(uv), free(nrm), free(tan), free(first_of), free(vid);
    return SC_OK;
}

static int gl_wrap(sc_wrap w) { return w == SC_WRAP_CLAMP ? 33071 : w == SC_WRAP_MIRROR ? 33648 : 10497; }

/* A JSON string (names are file-safe already, but quote what needs it). */
static void put_string(sc_buf *b, const char *s) {
    sc_buf_puts(b, "\"");
    for (; *s; s++) {
        unsigned char c = (unsigned char)*s;
        if (c == '"' || c == '\\') sc_buf_printf(b, "\\%c", c);
        else if (c < 0x20) sc_buf_printf(b, "\\u%04x", c);
        else sc_buf_append(b, s, 1);
    }
    sc_buf_puts(b, "\"");
}

static int texture_of(const sc_gltf_out_texture *t, int32_t n, int32_t mat, const char *slot) {
    for (int32_t i = 0; i < n; i++)
        if (t[i].material == mat && strcmp(t[i].slot, slot) == 0) return i;
    return -1;
}

/* The document: its JSON in g->json and its buffer in g->bin. bin_uri NULL
 * makes a .glb's (images in the buffer, buffer 0 the binary chunk); else a
 * .gltf's (images by their textures' uri, buffer 0 the file bin_uri). */
static int write_document(glb *g_out, const sc_mesh *const *levels, int32_t nlevels,
                          const sc_gltf_out_texture *textures, int32_t ntextures, const sc_material *constants,
                          const char *bin_uri, sc_error *err) {
    if (nlevels < 1) return sc_fail(err, SC_EINPUT, "glb: no levels");
    const sc_mesh *m0 = levels[0];
    for (int32_t l = 1; l < nlevels; l++)
        if (levels[l]->nmat != m0->nmat) return sc_fail(err, SC_EINPUT, "glb: level %d has other materials", (int)l);
    glb g = *g_out;
    sc_buf meshes, images, texs, samplers, materials;
    sc_buf_init(&meshes), sc_buf_init(&images), sc_buf_init(&texs), sc_buf_init(&samplers), sc_buf_init(&materials);
    int rc = SC_OK;
    bool tangents = false;
    for (int32_t i = 0; i < ntextures; i++) tangents |= strcmp(textures[i].slot, "normal") == 0;
    for (int32_t l = 0; l < nlevels && rc == SC_OK; l++) {
        sc_buf prims;
        sc_buf_init(&prims);
        bool first = true;
        sc_tangent_frames fr;
        rc = sc_tangent_frames_build(levels[l], &fr, err);
        for (int32_t mat = 0; mat < levels[l]->nmat && rc == SC_OK; mat++)
            rc = add_primitive(&g, levels[l], &fr, tangents, mat, &first, &prims, err);
        sc_tangent_frames_free(&fr);
        sc_buf_printf(&meshes, "%s{\"name\":\"lod%d\",\"primitives\":[", l ? "," : "", (int)l);
        sc_buf_append(&meshes, prims.data, prims.len);
        sc_buf_puts(&meshes, "]}");
        sc_buf_free(&prims);
    }
    /* images, samplers (one per texture: its wrap modes), textures */
    for (int32_t i = 0; i < ntextures && rc == SC_OK; i++) {
        if (bin_uri) {
            sc_buf_puts(&images, i ? ",{\"uri\":" : "{\"uri\":");
            put_string(&images, textures[i].uri ? textures[i].uri : "");
            sc_buf_puts(&images, "}");
        } else {
            int32_t view = add_view(&g, textures[i].bytes, textures[i].size, 0);
            sc_buf_printf(&images, "%s{\"bufferView\":%d,\"mimeType\":\"%s\"", i ? "," : "", view, textures[i].mime);
            if (textures[i].uri) {   /* the file name save measured it under */
                sc_buf_puts(&images, ",\"name\":");
                put_string(&images, textures[i].uri);
            }
            sc_buf_puts(&images, "}");
        }
        sc_buf_printf(&samplers, "%s{\"magFilter\":9729,\"minFilter\":9987,\"wrapS\":%d,\"wrapT\":%d}", i ? "," : "",
                      gl_wrap(textures[i].wrap_u), gl_wrap(textures[i].wrap_v));
        sc_buf_printf(&texs, "%s{\"sampler\":%d,\"source\":%d}", i ? "," : "", (int)i, (int)i);
    }
    /* materials: level 0's, with their textures */
    for (int32_t mat = 0; mat < m0->nmat; mat++) {
        int tc = texture_of(textures, ntextures, mat, "color"), tm = texture_of(textures, ntextures, mat, "metallic_roughness");
        int tn = texture_of(textures, ntextures, mat, "normal"), to = texture_of(textures, ntextures, mat, "occlusion");
        int te = texture_of(textures, ntextures, mat, "emissive");
        sc_buf_puts(&materials, mat ? ",{\"name\":" : "{\"name\":");
        put_string(&materials, m0->materials[mat]);
        sc_buf_puts(&materials, ",\"pbrMetallicRoughness\":{");
        if (tc >= 0) sc_buf_printf(&materials, "\"baseColorTexture\":{\"index\":%d},", tc);
        if (tm >= 0) sc_buf_printf(&materials, "\"metallicRoughnessTexture\":{\"index\":%d},", tm);
        const sc_material *c = &constants[mat];   /* what glTF defaults to is left out, but the factors */
        const double *bc = c->base_color;
        if (bc[0] != 1 || bc[1] != 1 || bc[2] != 1 || bc[3] != 1)
            sc_buf_printf(&materials, "\"baseColorFactor\":[%.17g,%.17g,%.17g,%.17g],", bc[0], bc[1], bc[2], bc[3]);
        sc_buf_printf(&materials, "\"metallicFactor\":%.17g,\"roughnessFactor\":%.17g}", c->metallic, c->roughness);
        if (tn >= 0) sc_buf_printf(&materials, ",\"normalTexture\":{\"index\":%d", tn);
        if (tn >= 0 && c->normal_scale != 1) sc_buf_printf(&materials, ",\"scale\":%.17g", c->normal_scale);
        if (tn >= 0) sc_buf_puts(&materials, "}");
        if (to >= 0) sc_buf_printf(&materials, ",\"occlusionTexture\":{\"index\":%d", to);
        if (to >= 0 && c->occlusion_strength != 1)
            sc_buf_printf(&materials, ",\"strength\":%.17g", c->occlusion_strength);
        if (to >= 0) sc_buf_puts(&materials, "}");
        if (te >= 0) sc_buf_printf(&materials, ",\"emissiveTexture\":{\"index\":%d}", te);
        if (c->emissive[0] != 0 || c->emissive[1] != 0 || c->emissive[2] != 0)
            sc_buf_printf(&materials, ",\"emissiveFactor\":[%.17g,%.17g,%.17g]", c->emissive[0], c->emissive[1],
                          c->emissive[2]);
        if (c->alpha_mode != SC_ALPHA_OPAQUE)
            sc_buf_printf(&materials, ",\"alphaMode\":\"%s\"", c->alpha_mode == SC_ALPHA_MASK ? "MASK" : "BLEND");
        if (c->alpha_mode == SC_ALPHA_MASK && c->alpha_cutoff != 0.5)
            sc_buf_printf(&materials, ",\"alphaCutoff\":%.17g", c->alpha_cutoff);
        if (c->double_sided) sc_buf_puts(&materials, ",\"doubleSided\":true");
        sc_buf_puts(&materials, "}");
    }
    /* the document */
    sc_buf *j = &g.json;
    sc_buf_puts(j, "{\"asset\":{\"version\":\"2.0\",\"generator\":\"seamcook\"},");
    if (nlevels > 1) sc_buf_puts(j, "\"extensionsUsed\":[\"MSFT_lod\"],");
    sc_buf_puts(j, "\"scene\":0,\"scenes\":[{\"nodes\":[0]}],\"nodes\":[{\"name\":\"lod0\",\"mesh\":0");
    if (nlevels > 1) {
        sc_buf_puts(j, ",\"extensions\":{\"MSFT_lod\":{\"ids\":[");
        for (int32_t l = 1; l < nlevels; l++) sc_buf_printf(j, "%s%d", l > 1 ? "," : "", (int)l);
        sc_buf_puts(j, "]}}");
    }
    sc_buf_puts(j, "}");
    for (int32_t l = 1; l < nlevels; l++) sc_buf_printf(j, ",{\"name\":\"lod%d\",\"mesh\":%d}", (int)l, (int)l);
    sc_buf_puts(j, "],\"meshes\":[");
    sc_buf_append(j, meshes.data, meshes.len);
    sc_buf_puts(j, "],\"materials\":[");
    sc_buf_append(j, materials.data, materials.len);
    sc_buf_puts(j, "]");
    if (ntextures > 0) {
        sc_buf_puts(j, ",\"textures\":[");
        sc_buf_append(j, texs.data, texs.len);
        sc_buf_puts(j, "],\"samplers\":[");
        sc_buf_append(j, samplers.data, samplers.len);
        sc_buf_puts(j, "],\"images\":[");
        sc_buf_append(j, images.data, images.len);
        sc_buf_puts(j, "]");
    }
    while (g.bin.len % 4) sc_buf_u8(&g.bin, 0);
    sc_buf_printf(j, ",\"accessors\":[");
    sc_buf_append(j, g.accessors.data, g.accessors.len);
    sc_buf_puts(j, "],\"bufferViews\":[");
    sc_buf_append(j, g.views.data, g.views.len);
    sc_buf_puts(j, "],\"buffers\":[{");
    if (bin_uri) {
        sc_buf_puts(j, "\"uri\":");
        put_string(j, bin_uri);
        sc_buf_puts(j, ",");
    }
    sc_buf_printf(j, "\"byteLength\":%zu}]}", g.bin.len);
    bool failed = g.json.failed || g.bin.failed || g.views.failed || g.accessors.failed || meshes.failed ||
                  images.failed || texs.failed || samplers.failed || materials.failed;
    if (rc == SC_OK && failed) rc = sc_fail(err, SC_ENOMEM, "glb: out of memory");
    sc_buf_free(&g.views), sc_buf_free(&g.accessors);
    sc_buf_free(&meshes), sc_buf_free(&images), sc_buf_free(&texs), sc_buf_free(&samplers), sc_buf_free(&materials);
    *g_out = g;
    return rc;
}

int sc_gltf_write_glb(const sc_mesh *const *levels, int32_t nlevels, const sc_gltf_out_texture *textures,
                      int32_t ntextures, const sc_material *constants, sc_buf *out, sc_error *err) {
    glb g = {0};
    sc_buf_init(&g.json), sc_buf_init(&g.bin), sc_buf_init(&g.views), sc_buf_init(&g.accessors);
    int rc = write_document(&g, levels, nlevels, textures, ntextures, constants, NULL, err);
    sc_buf *j = &g.json;
    while (j->len % 4) sc_buf_u8(j, ' ');
    if (rc == SC_OK && 12 + 8 + j->len + 8 + g.bin.len > UINT32_MAX) rc = sc_fail(err, SC_EINPUT, "glb: over 4 GB");
    if (rc == SC_OK) {
        sc_buf_u32(out, 0x46546C67u);   /* "glTF" */
        sc_buf_u32(out, 2);
        sc_buf_u32(out, (uint32_t)(12 + 8 + j->len + 8 + g.bin.len));
        sc_buf_u32(out, (uint32_t)j->len);
        sc_buf_u32(out, 0x4E4F534Au);   /* "JSON" */
        sc_buf_append(out, j->data, j->len);
        sc_buf_u32(out, (uint32_t)g.bin.len);
        sc_buf_u32(out, 0x004E4942u);   /* "BIN" */
        sc_buf_append(out, g.bin.data, g.bin.len);
        if (out->failed) rc = sc_fail(err, SC_ENOMEM, "glb: out of memory");
    }
    sc_buf_free(&g.json), sc_buf_free(&g.bin);
    return rc;
}

int sc_gltf_write_gltf(const sc_mesh *const *levels, int32_t nlevels, const sc_gltf_out_texture *textures,
                       int32_t ntextures, const sc_material *constants, const char *bin_uri, sc_buf *json,
                       sc_buf *bin, sc_error *err) {
    glb g = {0};
    sc_buf_init(&g.json), sc_buf_init(&g.bin), sc_buf_init(&g.views), sc_buf_init(&g.accessors);
    int rc = write_document(&g, levels, nlevels, textures, ntextures, constants, bin_uri, err);
    if (rc == SC_OK) {
        sc_buf_append(json, g.json.data, g.json.len);
        sc_buf_append(bin, g.bin.data, g.bin.len);
        if (json->failed || bin->failed) rc = sc_fail(err, SC_ENOMEM, "gltf: out of memory");
    }
    sc_buf_free(&g.json), sc_buf_free(&g.bin);
    return rc;
}
