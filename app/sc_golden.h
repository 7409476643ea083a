/* sc_golden.h - checking a run against what its graph file expects.
 *
 * Metric bounds (expect), golden images (expect_image) and golden metric files
 * (expect_metrics). Goldens live beside the graph file, in
 * goldens/<graph name>/: images as <node>/<file path with '/' as '_'>, metric
 * files as <node>.metrics.json. With `update`, goldens are (re)written from the
 * run instead of compared.
 */
#ifndef SC_GOLDEN_H
#define SC_GOLDEN_H

#include <stdio.h>

#include "sc_engine.h"

/* Check every expectation of run->graph. Files the nodes wrote are read from
 * out_dir; a failed image comparison writes a diff picture under
 * out_dir/diff/. Prints one line per failure (which expectation, the numbers,
 * the diff's path) to log. Returns how many failed. */
int sc_golden_check(const sc_run *run, const char *out_dir, bool update, FILE *log);

#endif
