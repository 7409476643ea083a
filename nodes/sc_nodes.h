/* sc_nodes.h - the node descriptors seamcook ships. Each is defined in its own
 * file in nodes/ and listed once in app/sc_registry.c. */
#ifndef SC_NODES_H
#define SC_NODES_H

#include "sc_node.h"

extern const sc_node_desc sc_node_load_atlas;    /* nodes/load_atlas.c */
extern const sc_node_desc sc_node_save;          /* nodes/save.c */
extern const sc_node_desc sc_node_procedural;    /* nodes/procedural.c */
extern const sc_node_desc sc_node_erase_seams;   /* nodes/erase_seams.c */
extern const sc_node_desc sc_node_decimate;      /* nodes/decimate.c */
extern const sc_node_desc sc_node_share_textures; /* nodes/share_textures.c */
extern const sc_node_desc sc_node_render;        /* nodes/render.c */
extern const sc_node_desc sc_node_bake_displacement; /* nodes/bake_displacement.c */
extern const sc_node_desc sc_node_mipmap;        /* nodes/mipmap.c */
extern const sc_node_desc sc_node_straighten;    /* nodes/straighten.c */
extern const sc_node_desc sc_node_quad_chartify; /* nodes/quad_chartify.c */
extern const sc_node_desc sc_node_gradient_domain; /* nodes/gradient_domain.c */

#endif
