/* share_textures.c - the node `share_textures`: one texture set for every LOD.
 *
 * Design note. Decimation works on the mesh alone (its input is a mesh port),
 * so new texture bytes never re-cook it. This node puts the textures back:
 * every level of the chain gets the very same IMAGE values as the atlas the
 * textures come from (shared by reference and digest, never copied). Levels
 * must have the same materials as that atlas, since each texture is bound to a
 * material.
 */
#include <string.h>

#include "sc_nodes.h"

static int run(sc_ctx *ctx, sc_error *err) {
    const sc_lods *in = sc_ctx_lods(ctx, "lods");
    const sc_atlas *textures = sc_ctx_atlas(ctx, "atlas");
    const sc_mesh *reference = textures->mesh->as.mesh;
    sc_lods *out = sc_lods_new();
    if (!out) return sc_fail(err, SC_ENOMEM, "out of memory");
    for (int32_t k = 0; k < in->count; k++) {
        const sc_atlas *level = in->levels[k]->as.atlas;
        const sc_mesh *mesh = level->mesh->as.mesh;
        if (mesh->nmat != reference->nmat) {
            sc_lods_free(out);
            return sc_fail(err, SC_EINPUT, "lods: level %d has %d materials, atlas has %d", k, mesh->nmat,
                           reference->nmat);
        }
        for (int32_t m = 0; m < mesh->nmat; m++)
            if (strcmp(mesh->materials[m], reference->materials[m]) != 0) {
                sc_lods_free(out);
                return sc_fail(err, SC_EINPUT, "lods: level %d material %d is '%s', atlas has '%s'", k, m,
                               mesh->materials[m], reference->materials[m]);
            }
        sc_atlas *a = sc_atlas_new(sc_value_retain(level->mesh));
        int rc = a ? sc_atlas_copy_materials(a, textures) : SC_ENOMEM;
        for (int32_t t = 0; rc == SC_OK && t < textures->ntex; t++) {
            const sc_texture *tex = &textures->textures[t];
            rc = sc_atlas_add_texture(a, tex->name, tex->material, tex->wrap_u, tex->wrap_v, tex->source,
                                      sc_value_retain(tex->image));
        }
        sc_value *v = rc == SC_OK ? sc_value_new_atlas(a) : NULL;
        if (rc != SC_OK) sc_atlas_free(a);
        if (!v || sc_lods_add(out, v) != SC_OK) {
            sc_lods_free(out);
            return sc_fail(err, SC_ENOMEM, "out of memory");
        }
    }
    sc_value *v = sc_value_new_lods(out);
    if (!v) return sc_fail(err, SC_ENOMEM, "out of memory");
    sc_ctx_metric(ctx, "levels", in->count);
    sc_ctx_metric(ctx, "textures", textures->ntex);
    sc_ctx_set_output(ctx, "lods", v);
    return SC_OK;
}

static const sc_port_desc inputs[] = {
    {.name = "lods", .kind = SC_KIND_LODS, .doc = "levels of detail (their own textures are dropped)"},
    {.name = "atlas", .kind = SC_KIND_ATLAS, .doc = "the atlas whose textures every level shares"},
};

static const sc_port_desc outputs[] = {
    {.name = "lods", .kind = SC_KIND_LODS, .doc = "the levels, each with the atlas's textures"},
};

const sc_node_desc sc_node_share_textures = {
    .type = "share_textures",
    .version = 1,
    .summary = "gives every level of detail the same texture set, shared by reference",
    .inputs = inputs,
    .ninputs = SC_COUNT(inputs),
    .outputs = outputs,
    .noutputs = SC_COUNT(outputs),
    .run = run,
};
