/* sc_atlas_ops.c - operations on atlases shared by bake_displacement and
 * mipmap (see sc_atlas_ops.h).
 *
 * Design note. The union keeps every mesh's face order and its materials, so
 * face f of mesh i is face f + (faces of meshes 0..i-1) of the union: the
 * seams of the union are exactly the seams of the parts. The erase helper
 * gives sc_erase the maps as slots "map<i>", so its results are erase_seams's
 * for the same options, byte for byte.
 */
#include "sc_atlas_ops.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sc_tangent.h"

static const sc_kernel *const atlas_ops_uses[] = {&sc_kernel_erase, &sc_kernel_tangent, NULL};
const sc_kernel sc_kernel_atlas_ops = {"atlas_ops", SC_ATLAS_OPS_VERSION, atlas_ops_uses};


sc_value *sc_atlas_ops_mesh_union(const sc_mesh *const *ms, int n) {
    if (n < 1 || !ms) return NULL;
    int64_t nv = 0, nu = 0, nf = 0;
    for (int i = 0; i < n; i++) {
        if (ms[i]->nmat != ms[0]->nmat) return NULL;
        for (int32_t k = 0; k < ms[0]->nmat; k++)
            if (strcmp(ms[i]->materials[k], ms[0]->materials[k]) != 0) return NULL;
        nv += ms[i]->nv, nu += ms[i]->nu, nf += ms[i]->nf;
    }
    if (nv > INT32_MAX || nu > INT32_MAX || nf > INT32_MAX) return NULL;
    if (3 * nf > INT32_MAX) return NULL;
    sc_mesh *u = sc_mesh_alloc((int32_t)nv, (int32_t)nu, (int32_t)(3 * nf), (int32_t)nf, ms[0]->nmat);
    if (!u) return NULL;
    for (int32_t k = 0; k < ms[0]->nmat; k++)
        if (!(u->materials[k] = sc_strdup(ms[0]->materials[k]))) {
            sc_mesh_free(u);
            return NULL;
        }
    int64_t ov = 0, ou = 0, of = 0;
    for (int i = 0; i < n; i++) {
        const sc_mesh *m = ms[i];
        if (m->nv) memcpy(u->V + 3 * ov, m->V, sizeof(double) * 3 * (size_t)m->nv);
        if (m->nu) memcpy(u->U + 2 * ou, m->U, sizeof(double) * 2 * (size_t)m->nu);
        double *normals = sc_tangent_corner_normals(m);
        if (!normals) {
            sc_mesh_free(u);
            return NULL;
        }
        if (m->nf) memcpy(u->N + 9 * of, normals, sizeof(double) * 9 * (size_t)m->nf);
        free(normals);
        for (int64_t f = 0; f < m->nf; f++) {
            for (int c = 0; c < 3; c++) {
                u->FV[3 * (of + f) + c] = (int32_t)(m->FV[3 * f + c] + ov);
                u->FU[3 * (of + f) + c] = (int32_t)(m->FU[3 * f + c] + ou);
                u->FN[3 * (of + f) + c] = (int32_t)(3 * (of + f) + c);
            }
            u->FM[of + f] = m->FM[f];
        }
        ov += m->nv, ou += m->nu, of += m->nf;
    }
    return sc_value_new_mesh(u);
}

sc_value *sc_atlas_ops_mesh_union_distinct(const sc_value *const *meshes, int n) {
    if (n < 1 || !meshes) return NULL;
    const sc_mesh **ms = calloc((size_t)n, sizeof *ms);
    if (!ms) return NULL;
    int distinct = 0;
    for (int i = 0; i < n; i++) {
        bool seen = false;
        for (int j = 0; j < i && !seen; j++)
            seen = sc_digest_equal(sc_value_digest(meshes[j]), sc_value_digest(meshes[i]));
        if (!seen) ms[distinct++] = meshes[i]->as.mesh;
    }
    sc_value *u = sc_atlas_ops_mesh_union(ms, distinct);
    free(ms);
    return u;
}

int sc_atlas_ops_erase(const sc_mesh *mesh, const sc_atlas_ops_map *maps, int n, const sc_erase_options *o,
                       int threads, sc_value **f32_out, sc_value **native_out, sc_error *err) {
    sc_texture *textures = calloc(n > 0 ? (size_t)n : 1, sizeof *textures);
    char (*names)[32] = calloc(n > 0 ? (size_t)n : 1, sizeof *names);
    if (!textures || !names) {
        free(textures), free(names);
        return sc_fail(err, SC_ENOMEM, "out of memory");
    }
    for (int i = 0; i < n; i++) {
        if (maps[i].slot && strlen(maps[i].slot) < sizeof names[i])
            snprintf(names[i], sizeof names[i], "%s", maps[i].slot);
        else
            snprintf(names[i], sizeof names[i], "map%d", i);
        textures[i] = (sc_texture){.name = names[i], .material = maps[i].material, .wrap_u = maps[i].wrap_u,
                                   .wrap_v = maps[i].wrap_v, .source = "", .image = maps[i].image};
    }
    sc_erase_result r;
    int rc = sc_erase(mesh, textures, n, o, threads, &r, err);
    for (int i = 0; i < n && rc == SC_OK; i++) {
        if (f32_out) f32_out[i] = sc_value_retain(r.f32[i]);
        if (native_out) native_out[i] = sc_value_retain(r.native[i]);
    }
    sc_erase_result_free(&r);
    free(textures), free(names);
    return rc;
}
