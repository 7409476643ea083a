/* bench_memory.c - how fast this machine maps fresh memory.
 *
 *   bench_memory [-r RUNS]
 *
 * Each run is a new process that first maps and touches HELD MiB (10, then
 * 700: about what pizza's load and the first half of its erase hold), then
 * times mapping and touching 475 MiB more (madvise MADV_POPULATE_WRITE, as
 * sc_alloc_array does; pizza's largest single block is 475 MiB). On the
 * 2-core machine the second figure drops well below the first in some
 * minutes and not in others: pages beyond what the machine used recently
 * come slower. The benchmarks with targets run several times for that
 * reason (runs.h).
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>

#include "runs.h"
#include "sc_base.h"

#ifndef MADV_POPULATE_WRITE
#define MADV_POPULATE_WRITE 23
#endif

#define MIB ((size_t)1 << 20)
#define BLOCK (475 * MIB)

static int map_after(void *ud, int out) {
    size_t held = *(const size_t *)ud;
    void *first = mmap(NULL, held, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (first == MAP_FAILED) return 1;
    if (madvise(first, held, MADV_POPULATE_WRITE) != 0) memset(first, 1, held);
    double t0 = sc_now();
    void *block = mmap(NULL, BLOCK, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (block == MAP_FAILED) return 1;
    if (madvise(block, BLOCK, MADV_POPULATE_WRITE) != 0) memset(block, 1, BLOCK);
    return bench_report_seconds(out, sc_now() - t0);
}

int main(int argc, char **argv) {
    int runs = 5;
    for (int i = 1; i < argc; i++)
        if (!strcmp(argv[i], "-r") && i + 1 < argc) runs = atoi(argv[++i]);
    if (runs < 1 || runs > 100) runs = 5;
    const size_t held[2] = {10 * MIB, 700 * MIB};
    printf("475 MiB of fresh memory mapped by a process already holding 10 or 700 MiB, %d runs each\n\n", runs);
    int failed = 0;
    for (int h = 0; h < 2; h++) {
        double seconds[100];
        int done = 0;
        printf("holding %3zu MiB:", held[h] / MIB);
        for (int r = 0; r < runs; r++)
            if (bench_in_child(map_after, (void *)&held[h], &seconds[done]) == 0)
                printf(" %.3f s (%.1f GB/s)", seconds[done], (double)BLOCK / 1e9 / seconds[done]), done++;
            else
                failed++;
        printf("\n");
        char name[32];
        snprintf(name, sizeof name, "after %zu MiB", held[h] / MIB);
        bench_summary(name, "475 MiB", seconds, done, 0);
    }
    return failed ? 1 : 0;
}
