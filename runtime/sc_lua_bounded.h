/* sc_lua_bounded.h - the graph sandbox's versions of the Lua library
 * functions that loop in C (private to runtime/sc_lua.c).
 *
 * Lua's instruction hook counts virtual-machine instructions only: a loop
 * inside a C function (a backtracking pattern match, string.rep of an empty
 * string 2^50 times, table.move over 2^40 slots) runs unseen and can hold the
 * runtime forever. These replacements do the same work and charge it, step
 * by step, to the graph's instruction budget through `charge`, which raises
 * a Lua error once a limit (instructions or wall-clock time) is exceeded.
 */
#ifndef SC_LUA_BOUNDED_H
#define SC_LUA_BOUNDED_H

#include <lua.h>
#include <stdint.h>

/* Adds `steps` to the graph's count; raises a Lua error past a limit. */
typedef void (*sc_lua_charge_fn)(lua_State *L, int64_t steps);

/* Replace string.find, string.match, string.gmatch, string.gsub,
 * string.rep, table.move and table.sort in the loaded string and table
 * libraries (and so in the string metatable's __index). */
void sc_lua_open_bounded(lua_State *L, sc_lua_charge_fn charge);

#endif
