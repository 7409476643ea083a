/* sc_registry.h - the one table of node descriptors the engine knows. */
#ifndef SC_REGISTRY_H
#define SC_REGISTRY_H

#include "sc_node.h"

/* The descriptor for a type name, or NULL. */
const sc_node_desc *sc_registry_find(const char *type);
/* All descriptors, sorted by type name; *count receives how many. */
const sc_node_desc *const *sc_registry_all(int *count);

#endif
