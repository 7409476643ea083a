/* fuzz_config.c - libFuzzer entry point for the project file (seamcook.conf),
 * the farm's asset list and the remote cache's wire formats: the input is
 * parsed as a project file, as an asset list (its paths are looked up
 * below a folder that does not exist, so only its lines are exercised), as
 * an ActionResult protobuf and as an action record. Each either
 * fails with a message or gives values that hold what the format promises
 * (every header has a colon; every output's path is a string without NUL).
 * Build with -DSC_FUZZ=ON (clang), run e.g.
 *   ./build-fuzz/fuzz_config -max_total_time=30 /tmp/config-corpus tests/data/config
 */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "sc_config.h"
#include "sc_farm.h"
#include "sc_remote.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    if (size > 65536) return 0;
    sc_error err;
    sc_config c;
    sc_config_init(&c);
    if (sc_config_parse((const char *)data, size, "fuzz.conf", &c, &err) == SC_OK)
        for (int i = 0; i < c.nheaders; i++)
            if (!strchr(c.headers[i], ':')) abort();
    sc_config_free(&c);

    char **paths;
    int count;
    if (sc_farm_parse_assets((const char *)data, size, "fuzz.list", "/nonexistent-fuzz", &paths, &count, &err) == SC_OK)
        sc_farm_paths_free(paths);

    sc_remote_output *outs;
    int n;
    if (sc_remote_decode_result(data, size, &outs, &n, &err) == SC_OK) {
        sc_buf again;
        sc_buf_init(&again);
        for (int i = 0; i < n; i++)
            if (!outs[i].path || outs[i].size < 0) abort();
        if (sc_remote_encode_result(outs, n, &again) != SC_OK) abort();
        sc_remote_output *back;
        int m;
        if (sc_remote_decode_result(again.data, again.len, &back, &m, &err) != SC_OK || m != n) abort();
        sc_remote_outputs_free(back, m);
        sc_buf_free(&again);
        sc_remote_outputs_free(outs, n);
    }

    sc_cache_action a;
    if (sc_remote_record_decode((const char *)data, size, &a, &err) == SC_OK) {
        for (int i = 0; i < a.ndeps; i++)
            if (!a.deps[i].path) abort();
        sc_cache_action_free(&a);
    }
    return 0;
}
