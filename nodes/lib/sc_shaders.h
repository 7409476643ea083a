/* sc_shaders.h - the GLSL sources of shaders/, embedded at build time.
 *
 * shaders/embed.cmake generates the implementation (sc_shaders_embedded.c in
 * the build folder) from every .glsl file in shaders/, so a binary never reads
 * shader files at run time and a shader edit rebuilds what uses it.
 */
#ifndef SC_SHADERS_H
#define SC_SHADERS_H

/* The text of shaders/<name> (e.g. "render_vs.glsl"), NUL-terminated, or
 * NULL when there is no such file. */
const char *sc_shader_source(const char *name);

#endif
