/* sc_farm.h - cooking one graph over many assets on a Slurm cluster.
 *
 *   seamcook farm submit GRAPH --assets LIST [options of run]
 *   seamcook farm status [--out DIR]
 *
 * submit reads LIST (one asset path a line, relative to the list's folder;
 * blank lines and # comments skipped), writes the job's folder
 * OUT/.seamcook-farm/ (the assets, absolute, one a line; the batch script;
 * later the job id) and submits a Slurm job array with sbatch, a task per
 * asset. Task i runs `seamcook run GRAPH --set PARAM=ASSET_i --out
 * OUT/<i>_<asset name>` with the cache and the other options given to
 * submit, and leaves its summary (`--json`) as task_<i>.json. Several tasks
 * share the cache (leases: one cook per action) and, given one, the remote
 * cache.
 *
 * status reads that folder, and asks squeue which tasks are pending or
 * running: one line per task and a count of each state.
 */
#ifndef SC_FARM_H
#define SC_FARM_H

#include <stdio.h>

#include "sc_base.h"

typedef struct sc_farm_job {
    const char *seamcook;          /* the command each task runs (absolute) */
    const char *graph;             /* the graph file */
    const char *assets;            /* the asset list file */
    const char *param;             /* the graph parameter an asset goes into ("mesh") */
    const char *out_dir;           /* every task's --out lies below it */
    const char *const *run_args;   /* more arguments for each task's `seamcook run` */
    int nrun_args;
} sc_farm_job;

/* The assets of a list's text: one path a line, made absolute against
 * `dir`; each must be a file (an error names list:line). *paths: a NULL-
 * terminated array of new strings, *count of them (free with
 * sc_farm_paths_free). */
int sc_farm_parse_assets(const char *text, size_t n, const char *list, const char *dir, char ***paths, int *count,
                         sc_error *err);
void sc_farm_paths_free(char **paths);

/* Write the job's folder and submit it; *job_id receives Slurm's id (a new
 * string). Fails naming sbatch's message when it refuses. */
int sc_farm_submit(const sc_farm_job *job, char **job_id, sc_error *err);

/* Print the job's state to out; *unfinished and *failed count tasks still
 * pending or running, and tasks that failed or were lost. */
int sc_farm_status(const char *out_dir, FILE *out, int *unfinished, int *failed, sc_error *err);

#endif
