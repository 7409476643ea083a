/* sc_farm.c - cooking one graph over many assets on a Slurm cluster (see
 * sc_farm.h).
 *
 * Design note: Slurm does the scheduling; seamcook only writes what a task
 * needs to find its asset and submits an array job. A task knows its asset
 * by its index (SLURM_ARRAY_TASK_ID, the line of the assets file), so the
 * job script is the same for every task and the folder holds everything a
 * later `farm status` reads: no state lives anywhere else. A task's outcome
 * is its `--json` summary (exit_status and totals); a task that Slurm no
 * longer lists and that left no summary was lost (killed, or its node
 * died). Commands are run through /bin/sh with every argument single-quoted.
 */
#include "sc_farm.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cjson/cJSON.h>

#define FARM_DIR ".seamcook-farm"
#define MAX_LIST_BYTES (64u << 20)

void sc_farm_paths_free(char **paths) {
    for (int i = 0; paths && paths[i]; i++) free(paths[i]);
    free(paths);
}

int sc_farm_parse_assets(const char *text, size_t n, const char *list, const char *dir, char ***paths, int *count,
                         sc_error *err) {
    *paths = NULL;
    *count = 0;
    if (memchr(text, 0, n)) return sc_fail(err, SC_EINPUT, "%s: holds a NUL byte: not a list of paths", list);
    char **out = NULL;
    int len = 0;
    const char *p = text, *end = text + n;
    for (int line = 1; p < end; line++) {
        const char *eol = memchr(p, '\n', (size_t)(end - p));
        if (!eol) eol = end;
        const char *s = p, *e = eol;
        while (s < e && (*s == ' ' || *s == '\t')) s++;
        while (e > s && (e[-1] == ' ' || e[-1] == '\t' || e[-1] == '\r')) e--;
        p = eol + 1;
        if (s == e || *s == '#') continue;
        char *rel = sc_strndup(s, (size_t)(e - s));
        char *abs = rel ? sc_path_resolve(dir, rel) : NULL;
        char **grown = abs ? sc_realloc_array(out, (size_t)len + 2, sizeof *grown) : NULL;
        if (!grown) {
            free(rel), free(abs);
            sc_farm_paths_free(out);
            return sc_fail(err, SC_ENOMEM, "out of memory");
        }
        out = grown;
        out[len] = NULL;
        struct stat st;
        if (stat(abs, &st) != 0 || !S_ISREG(st.st_mode)) {
            sc_fail(err, SC_EINPUT, "%s:%d: '%.200s' is not a file", list, line, rel);
            free(rel), free(abs);
            sc_farm_paths_free(out);
            return SC_EINPUT;
        }
        free(rel);
        out[len++] = abs;
        out[len] = NULL;
    }
    if (len == 0) {
        sc_farm_paths_free(out);
        return sc_fail(err, SC_EINPUT, "%s: names no asset", list);
    }
    *paths = out;
    *count = len;
    return SC_OK;
}

/* s single-quoted for /bin/sh. */
static void put_quoted(sc_buf *b, const char *s) {
    sc_buf_u8(b, '\'');
    for (; *s; s++) {
        if (*s == '\'') sc_buf_puts(b, "'\\''");
        else sc_buf_u8(b, (uint8_t)*s);
    }
    sc_buf_u8(b, '\'');
}

/* Run a command and read its standard output (at most 64 KiB). */
static int run_reading(const char *cmd, sc_buf *out, int *status, sc_error *err) {
    FILE *f = popen(cmd, "r");
    if (!f) return sc_fail(err, SC_EIO, "cannot run '%.100s': %s", cmd, strerror(errno));
    char chunk[4096];
    size_t got;
    while ((got = fread(chunk, 1, sizeof chunk, f)) > 0)
        if (out->len < 65536) sc_buf_append(out, chunk, got);
    int st = pclose(f);
    *status = st == -1 ? -1 : WIFEXITED(st) ? WEXITSTATUS(st) : 128;
    sc_buf_u8(out, 0);
    out->len--;
    return out->failed ? sc_fail(err, SC_ENOMEM, "out of memory") : SC_OK;
}

/* A folder name for an asset: its file name without the extension, other
 * characters than [A-Za-z0-9._-] as '_'. */
static char *task_name(int i, const char *asset) {
    const char *base = strrchr(asset, '/');
    base = base ? base + 1 : asset;
    const char *dot = strrchr(base, '.');
    size_t n = dot && dot > base ? (size_t)(dot - base) : strlen(base);
    char *name = sc_strprintf("%d_%.*s", i, (int)(n > 80 ? 80 : n), base);
    for (char *c = name ? strchr(name, '_') + 1 : NULL; c && *c; c++)
        if (!((*c >= 'a' && *c <= 'z') || (*c >= 'A' && *c <= 'Z') || (*c >= '0' && *c <= '9') || *c == '.' ||
              *c == '-'))
            *c = '_';
    return name;
}

static int write_text(const char *dir, const char *name, const char *text, sc_error *err) {
    char *path = sc_path_join(dir, name);
    int rc = path ? sc_write_file_atomic(path, text, strlen(text), err) : sc_fail(err, SC_ENOMEM, "out of memory");
    free(path);
    return rc;
}

/* The batch script: task i takes line i + 1 of the assets file. */
static char *job_script(const sc_farm_job *job, const char *farm, const char *out_abs, char **assets, int n) {
    sc_buf b;
    sc_buf_init(&b);
    sc_buf_puts(&b, "#!/bin/sh\n# written by seamcook farm submit: one task per asset\nset -u\ncase \"$SLURM_ARRAY_TASK_ID\" in\n");
    for (int i = 0; i < n; i++) {
        char *name = task_name(i, assets[i]);
        sc_buf_printf(&b, "%d) asset=", i);
        put_quoted(&b, assets[i]);
        sc_buf_puts(&b, " out=");
        char *out = name ? sc_path_join(out_abs, name) : NULL;
        put_quoted(&b, out ? out : "");
        sc_buf_puts(&b, " ;;\n");
        free(out), free(name);
    }
    sc_buf_puts(&b, "*) echo \"no asset for task $SLURM_ARRAY_TASK_ID\" >&2; exit 2 ;;\nesac\n");
    put_quoted(&b, job->seamcook);
    sc_buf_puts(&b, " run ");
    put_quoted(&b, job->graph);
    sc_buf_puts(&b, " --set ");
    sc_buf_printf(&b, "\"%s=$asset\" --out \"$out\" --json", job->param);
    for (int i = 0; i < job->nrun_args; i++) {
        sc_buf_u8(&b, ' ');
        put_quoted(&b, job->run_args[i]);
    }
    sc_buf_puts(&b, " > ");
    put_quoted(&b, farm);
    sc_buf_puts(&b, "/task_$SLURM_ARRAY_TASK_ID.json.tmp && mv ");
    put_quoted(&b, farm);
    sc_buf_puts(&b, "/task_$SLURM_ARRAY_TASK_ID.json.tmp ");
    put_quoted(&b, farm);
    sc_buf_puts(&b, "/task_$SLURM_ARRAY_TASK_ID.json\n");
    /* a failed cook still leaves its summary, which says why */
    sc_buf_puts(&b, "status=$?\n[ -f ");
    put_quoted(&b, farm);
    sc_buf_puts(&b, "/task_$SLURM_ARRAY_TASK_ID.json.tmp ] && mv ");
    put_quoted(&b, farm);
    sc_buf_puts(&b, "/task_$SLURM_ARRAY_TASK_ID.json.tmp ");
    put_quoted(&b, farm);
    sc_buf_puts(&b, "/task_$SLURM_ARRAY_TASK_ID.json\nexit $status\n");
    return sc_buf_take_string(&b);
}

int sc_farm_submit(const sc_farm_job *job, char **job_id, sc_error *err) {
    *job_id = NULL;
    sc_buf list;
    sc_buf_init(&list);
    int rc = sc_read_file(job->assets, MAX_LIST_BYTES, &list, err);
    char cwd[4096];
    char *list_abs = rc == SC_OK && getcwd(cwd, sizeof cwd) ? sc_path_resolve(cwd, job->assets) : NULL;
    char *list_dir = list_abs ? sc_path_dirname(list_abs) : NULL;
    char *out_abs = list_abs ? sc_path_resolve(cwd, job->out_dir) : NULL;
    char *farm = out_abs ? sc_path_join(out_abs, FARM_DIR) : NULL;
    if (rc == SC_OK && (!list_dir || !farm)) rc = sc_fail(err, SC_ENOMEM, "out of memory");
    char **assets = NULL;
    int n = 0;
    if (rc == SC_OK)
        rc = sc_farm_parse_assets(list.data ? (const char *)list.data : "", list.len, job->assets, list_dir, &assets,
                                  &n, err);
    sc_buf_free(&list);
    if (rc == SC_OK) rc = sc_make_dirs(farm, err);
    char *script = rc == SC_OK ? job_script(job, farm, out_abs, assets, n) : NULL;
    if (rc == SC_OK && !script) rc = sc_fail(err, SC_ENOMEM, "out of memory");
    if (rc == SC_OK) rc = write_text(farm, "job.sh", script, err);
    sc_buf text;
    sc_buf_init(&text);
    for (int i = 0; rc == SC_OK && i < n; i++) sc_buf_printf(&text, "%s\n", assets[i]);
    if (rc == SC_OK) rc = write_text(farm, "assets", text.data ? (const char *)text.data : "", err);
    /* sbatch --parsable prints "ID" or "ID;cluster" */
    sc_buf cmd, answer;
    sc_buf_init(&cmd);
    sc_buf_init(&answer);
    if (rc == SC_OK) {
        sc_buf_printf(&cmd, "sbatch --parsable --job-name=seamcook --array=0-%d --output=", n - 1);
        char *log = sc_strprintf("%s/task_%%a.log", farm), *js = sc_path_join(farm, "job.sh");
        put_quoted(&cmd, log ? log : "");
        sc_buf_u8(&cmd, ' ');
        put_quoted(&cmd, js ? js : "");
        sc_buf_puts(&cmd, " 2>&1");
        free(log), free(js);
        char *c = sc_buf_take_string(&cmd);
        int status = 0;
        rc = c ? run_reading(c, &answer, &status, err) : sc_fail(err, SC_ENOMEM, "out of memory");
        free(c);
        const char *a = answer.data ? (const char *)answer.data : "";
        size_t idlen = strspn(a, "0123456789");
        if (rc == SC_OK && (status != 0 || idlen == 0))
            rc = sc_fail(err, SC_EIO, "sbatch refused the job (status %d): %.300s", status, a);
        if (rc == SC_OK) *job_id = sc_strndup(a, idlen);
        if (rc == SC_OK) {
            char *line = sc_strprintf("%s\n", *job_id);
            rc = line ? write_text(farm, "job", line, err) : sc_fail(err, SC_ENOMEM, "out of memory");
            free(line);
        }
    }
    sc_buf_free(&cmd), sc_buf_free(&answer), sc_buf_free(&text);
    sc_farm_paths_free(assets);
    free(script), free(farm), free(out_abs), free(list_dir), free(list_abs);
    return rc;
}

/* A task's summary: "done ..." or "failed ...", or NULL when there is none. */
static char *task_outcome(const char *farm, int i, bool *ok) {
    char *path = sc_strprintf("%s/task_%d.json", farm, i);
    sc_buf b;
    sc_buf_init(&b);
    char *line = NULL;
    if (path && sc_read_file(path, 1u << 28, &b, NULL) == SC_OK) {
        cJSON *o = cJSON_ParseWithLength(b.data ? (const char *)b.data : "", b.len);
        const cJSON *st = cJSON_GetObjectItemCaseSensitive(o, "exit_status");
        const cJSON *totals = cJSON_GetObjectItemCaseSensitive(o, "totals");
        const cJSON *error = cJSON_GetObjectItemCaseSensitive(o, "error");
        int ran = cJSON_GetObjectItemCaseSensitive(totals, "ran") ?
                      cJSON_GetObjectItemCaseSensitive(totals, "ran")->valueint : 0;
        int cached = cJSON_GetObjectItemCaseSensitive(totals, "cached") ?
                         cJSON_GetObjectItemCaseSensitive(totals, "cached")->valueint : 0;
        *ok = cJSON_IsNumber(st) && st->valueint == 0;
        if (*ok) line = sc_strprintf("done (%d cooked, %d cached)", ran, cached);
        else line = sc_strprintf("failed: %.300s", cJSON_IsString(error) ? error->valuestring : "no summary");
        cJSON_Delete(o);
    }
    sc_buf_free(&b);
    free(path);
    return line;
}

int sc_farm_status(const char *out_dir, FILE *out, int *unfinished, int *failed, sc_error *err) {
    *unfinished = *failed = 0;
    char *farm = sc_path_join(out_dir, FARM_DIR);
    char *job_path = farm ? sc_path_join(farm, "job") : NULL, *assets_path = farm ? sc_path_join(farm, "assets") : NULL;
    sc_buf job, list, queue;
    sc_buf_init(&job), sc_buf_init(&list), sc_buf_init(&queue);
    int rc = job_path && assets_path ? SC_OK : sc_fail(err, SC_ENOMEM, "out of memory");
    if (rc == SC_OK && (sc_read_file(job_path, 4096, &job, NULL) != SC_OK ||
                        sc_read_file(assets_path, MAX_LIST_BYTES, &list, NULL) != SC_OK))
        rc = sc_fail(err, SC_EUSAGE, "%s: no farm job here (seamcook farm submit writes one)", out_dir);
    char id[64] = "";
    if (rc == SC_OK) {
        size_t n = strspn((const char *)job.data, "0123456789");
        if (n == 0 || n >= sizeof id) rc = sc_fail(err, SC_EINPUT, "%s: not a job id", job_path);
        else memcpy(id, job.data, n), id[n] = 0;
    }
    /* squeue: "TASK STATE" per pending or running task ("%K": the array index) */
    if (rc == SC_OK) {
        char *cmd = sc_strprintf("squeue --noheader --array --jobs=%s --format='%%K %%T' 2>/dev/null", id);
        int status = 0;
        if (cmd) run_reading(cmd, &queue, &status, NULL);
        free(cmd);
    }
    int i = 0;
    const char *q = queue.data ? (const char *)queue.data : "";
    for (const char *p = list.data ? (const char *)list.data : ""; rc == SC_OK && *p; i++) {
        const char *eol = strchr(p, '\n');
        int len = (int)(eol ? eol - p : (long)strlen(p));
        bool ok = false;
        char *outcome = task_outcome(farm, i, &ok);
        char state[32] = "";
        char key[32];
        snprintf(key, sizeof key, "%d ", i);
        for (const char *l = q; *l && !state[0];) {   /* this task's line of squeue */
            if (!strncmp(l, key, strlen(key))) sscanf(l + strlen(key), "%31s", state);
            l = strchr(l, '\n');
            l = l ? l + 1 : "";
        }
        if (outcome) {
            fprintf(out, "task %d  %-8s %.*s: %s\n", i, ok ? "done" : "failed", len, p, outcome);
            if (!ok) (*failed)++;
        } else if (state[0]) {
            fprintf(out, "task %d  %-8s %.*s\n", i, state[0] == 'P' ? "pending" : "running", len, p);
            (*unfinished)++;
        } else {
            fprintf(out, "task %d  %-8s %.*s: no summary and not in the queue\n", i, "lost", len, p);
            (*failed)++;
        }
        free(outcome);
        p = eol ? eol + 1 : p + len;
    }
    if (rc == SC_OK)
        fprintf(out, "job %s: %d tasks, %d done, %d pending or running, %d failed or lost\n", id, i,
                i - *unfinished - *failed, *unfinished, *failed);
    sc_buf_free(&job), sc_buf_free(&list), sc_buf_free(&queue);
    free(job_path), free(assets_path), free(farm);
    return rc;
}
