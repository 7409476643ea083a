/* sc_report.h - what a run says about itself: report.json and report.html. */
#ifndef SC_REPORT_H
#define SC_REPORT_H

#include "sc_engine.h"

/* report.json: per node its type, key, status (cached or ran), seconds,
 * metrics, outputs, files written and files read. Caller frees. */
char *sc_run_report_json(const sc_run *r);

/* report.html: one self-contained page (no network) with every node's
 * status and metrics and, per level of detail, its renders side by side with
 * its metrics; pictures are the PNG files the run wrote, linked relative to
 * the page. Caller frees. */
char *sc_run_report_html(const sc_run *r);

#endif
