/* sc_registry.c - the one table of node types. Adding a node means adding its
 * descriptor here (kept sorted by type name) and in nodes/sc_nodes.h. */
#include "sc_registry.h"

#include <string.h>

#include "sc_nodes.h"

static const sc_node_desc *const registry[] = {
    &sc_node_bake_displacement,
    &sc_node_decimate,
    &sc_node_erase_seams,
    &sc_node_gradient_domain,
    &sc_node_quad_chartify,
    &sc_node_load_atlas,
    &sc_node_mipmap,
    &sc_node_procedural,
    &sc_node_render,
    &sc_node_save,
    &sc_node_share_textures,
    &sc_node_straighten,
    NULL,
};

const sc_node_desc *sc_registry_find(const char *type) {
    for (int i = 0; registry[i]; i++)
        if (strcmp(registry[i]->type, type) == 0) return registry[i];
    return NULL;
}

const sc_node_desc *const *sc_registry_all(int *count) {
    int n = 0;
    while (registry[n]) n++;
    *count = n;
    return registry;
}
