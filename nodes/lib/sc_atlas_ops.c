/* sc_atlas_ops.c - operations on atlases shared by bake_displacement and
 * mipmap (see sc_atlas_ops.h).
 *
 * Design note. The union keeps every mesh's face order and its materials, so
 * face f of mesh i is face f + (faces of meshes 0..i-1) of the union: the
 * seams of the union are exactly the seams of the parts. The erase helper
 * builds an atlas of the mesh and the maps (slots "map<i>") and runs the
 * erase_seams node through sc_ctx, a pure function of its inputs and
 * parameters, so the result is the node's, byte for byte.
 */
#include "sc_atlas_ops.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sc_exec.h"

extern const sc_node_desc sc_node_erase_seams;

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
    sc_mesh *u = sc_mesh_alloc((int32_t)nv, (int32_t)nu, 0, (int32_t)nf, ms[0]->nmat);
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
        for (int64_t f = 0; f < m->nf; f++) {
            for (int c = 0; c < 3; c++) {
                u->FV[3 * (of + f) + c] = (int32_t)(m->FV[3 * f + c] + ov);
                u->FU[3 * (of + f) + c] = (int32_t)(m->FU[3 * f + c] + ou);
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
        for (int j = 0; j < i && !seen; j++) seen = sc_digest_equal(&meshes[j]->digest, &meshes[i]->digest);
        if (!seen) ms[distinct++] = meshes[i]->as.mesh;
    }
    sc_value *u = sc_atlas_ops_mesh_union(ms, distinct);
    free(ms);
    return u;
}

int sc_atlas_ops_erase(sc_value *mesh, const sc_atlas_ops_map *maps, int n, double gap_tolerance,
                       const char *quantize, const char *const *params, int threads, sc_value **f32_out,
                       sc_value **native_out, sc_error *err) {
    sc_atlas *a = sc_atlas_new(sc_value_retain(mesh));
    if (!a) return sc_fail(err, SC_ENOMEM, "out of memory");
    for (int i = 0; i < n; i++) {
        char name[32];
        snprintf(name, sizeof name, "map%d", i);
        if (sc_atlas_add_texture(a, name, maps[i].material, maps[i].wrap_u, maps[i].wrap_v, "",
                                 sc_value_retain(maps[i].image)) != SC_OK) {
            sc_atlas_free(a);
            return sc_fail(err, SC_ENOMEM, "out of memory");
        }
    }
    sc_value *av = sc_value_new_atlas(a);
    if (!av) return sc_fail(err, SC_ENOMEM, "out of memory");
    sc_ctx *ctx = sc_ctx_new(&sc_node_erase_seams, NULL, NULL);
    int rc = ctx ? SC_OK : sc_fail(err, SC_ENOMEM, "out of memory");
    char tol[64];
    snprintf(tol, sizeof tol, "%.17g", gap_tolerance);
    if (rc == SC_OK) rc = sc_ctx_set_input(ctx, "atlas", av);
    if (rc == SC_OK) rc = sc_ctx_set_param(ctx, "gap_tolerance", tol, err);
    if (rc == SC_OK && quantize) rc = sc_ctx_set_param(ctx, "quantize", quantize, err);
    for (int i = 0; rc == SC_OK && params && params[i] && params[i + 1]; i += 2)
        rc = sc_ctx_set_param(ctx, params[i], params[i + 1], err);
    if (rc == SC_OK) sc_ctx_set_threads(ctx, threads);
    if (rc == SC_OK) rc = sc_ctx_run(ctx, err);
    if (rc == SC_OK) {
        const sc_atlas *f32 = sc_ctx_output(ctx, 0)->as.atlas, *native = sc_ctx_output(ctx, 1)->as.atlas;
        for (int i = 0; i < n && rc == SC_OK; i++) {
            char name[32];
            snprintf(name, sizeof name, "map%d", i);
            if (sc_atlas_find_texture(f32, maps[i].material, name) < 0 ||
                sc_atlas_find_texture(native, maps[i].material, name) < 0)
                rc = sc_fail(err, SC_EINPUT, "erase_seams lost image %d", i);
        }
        for (int i = 0; i < n && rc == SC_OK; i++) {
            char name[32];
            snprintf(name, sizeof name, "map%d", i);
            if (f32_out) f32_out[i] = sc_value_retain(f32->textures[sc_atlas_find_texture(f32, maps[i].material, name)].image);
            if (native_out)
                native_out[i] =
                    sc_value_retain(native->textures[sc_atlas_find_texture(native, maps[i].material, name)].image);
        }
    }
    sc_ctx_free(ctx);
    sc_value_release(av);
    return rc;
}
