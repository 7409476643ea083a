/* sc_lua.h - running a graph file (Lua 5.4, sandboxed) to build an sc_graph.
 *
 * The sandbox opens base, string, table, math and utf8 only; removes dofile,
 * loadfile, require, collectgarbage, string.dump and every way to load
 * bytecode; bounds instructions (C loops of the string and table libraries
 * included), memory and wall-clock time. Each registered node type is a
 * global constructor taking one table: input ports (node handles) and
 * parameters by name, plus an optional `name`. It returns a handle; for a
 * node with several outputs, handle.<port> selects one. `param(name, default)`
 * reads `--set name=value`; a setting `node.param` that no param() reads sets
 * that parameter of the node named `node`. Running the file only builds the
 * graph.
 */
#ifndef SC_LUA_H
#define SC_LUA_H

#include "sc_graph.h"

typedef struct sc_setting {
    const char *name;
    const char *value;
} sc_setting;

typedef struct sc_lua_limits {
    int64_t max_instructions;   /* 0: the default (100 million) */
    size_t max_memory;          /* 0: the default (256 MiB) */
    double max_seconds;         /* wall clock; 0: the default (5 s) */
} sc_lua_limits;

/* Build the graph described by the file at `path`, with `types` as the node
 * constructors (the engine passes sc_registry_all; tests pass their own).
 * Every --set must be read by some param() call or name a node's parameter,
 * or it is an error naming it. On failure *out is NULL and err says
 * file:line. Errors: SC_EUSAGE for what the settings got wrong (a value that
 * is not of its type, that a node refuses, an unknown node or parameter, a
 * setting nothing reads, a required one missing), SC_EINPUT for graph
 * problems. */
int sc_lua_build(const char *path, const sc_node_desc *const *types, int ntypes,
                 const sc_setting *settings, int nsettings,
                 const sc_lua_limits *limits, sc_graph **out, sc_error *err);

#endif
