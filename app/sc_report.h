/* sc_report.h - what a run says about itself: report.json, report.html, the
 * --json summary and the JUnit XML of `seamcook test --junit`. */
#ifndef SC_REPORT_H
#define SC_REPORT_H

#include "sc_engine.h"

/* report.json: per node its type, key, status (cached or ran), seconds,
 * metrics, outputs, files written and files read. Caller frees. */
char *sc_run_report_json(const sc_run *r);

/* --json: report.json's content and "exit_status", with "error" (the
 * message) when there is one; with no run (the graph did not build, the
 * cache did not open) the graph file, an empty "nodes", the status and the
 * error. Caller frees. */
char *sc_run_summary_json(const char *graph, const sc_run *r, int exit_status, const char *error);

/* One graph test file's outcome, for sc_junit_xml. */
typedef struct sc_test_case {
    const char *name;       /* the graph test file */
    double seconds;
    const char *failure;    /* what failed, as printed; NULL when it passed */
} sc_test_case;

/* JUnit XML (test --junit): one testsuite, a testcase per graph test file,
 * a <failure> holding the message of each that failed. Caller frees. */
char *sc_junit_xml(const sc_test_case *cases, int n);

/* report.html: one self-contained page (no network). First the warnings,
 * then per render node that checked levels of detail its reference's
 * contact sheet above each level's with one row of numbers per level, then
 * inline SVG plots (faces against Hausdorff distance, seam energy per mip
 * level), then every node's status, metrics and pictures. Pictures are the
 * PNG files the run wrote, linked relative to the page. Caller frees. */
char *sc_run_report_html(const sc_run *r);

#endif
