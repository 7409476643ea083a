/* runs.c - repeated benchmark runs (runs.h). */
#include "runs.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

int bench_report_seconds(int out, double seconds) {
    return write(out, &seconds, sizeof seconds) == (ssize_t)sizeof seconds ? 0 : 1;
}

int bench_in_child(int (*fn)(void *ud, int out), void *ud, double *seconds) {
    int fd[2];
    if (pipe(fd) != 0) return 1;
    fflush(stdout);
    pid_t pid = fork();
    if (pid == 0) {
        close(fd[0]);
        int rc = fn(ud, fd[1]);
        fflush(stdout);
        _exit(rc);
    }
    close(fd[1]);
    int got = pid > 0 && read(fd[0], seconds, sizeof *seconds) == (ssize_t)sizeof *seconds;
    close(fd[0]);
    int st = 0;
    if (pid < 0 || waitpid(pid, &st, 0) < 0 || !WIFEXITED(st) || WEXITSTATUS(st) != 0) return 1;
    return got ? 0 : 1;
}

static int cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

void bench_summary(const char *name, const char *what, double *seconds, int n, double target) {
    if (n < 2) return;
    qsort(seconds, (size_t)n, sizeof *seconds, cmp_double);
    double median = n % 2 ? seconds[n / 2] : 0.5 * (seconds[n / 2 - 1] + seconds[n / 2]);
    printf("%-12s %d runs: %s median %.2f s, range %.2f-%.2f s", name, n, what, median, seconds[0], seconds[n - 1]);
    if (target > 0) {
        int met = 0;
        for (int i = 0; i < n; i++) met += seconds[i] <= target;
        printf("; target <= %.2g s met in %d of %d", target, met, n);
    }
    printf("\n");
}

/* A "Key:   N kB" line of /proc/self/status, in MiB. */
static double status_mb(const char *key) {
    FILE *f = fopen("/proc/self/status", "r");
    if (!f) return -1;
    char line[256];
    double kb = -1;
    size_t n = strlen(key);
    while (fgets(line, sizeof line, f))
        if (strncmp(line, key, n) == 0) kb = atof(line + n);
    fclose(f);
    return kb / 1024.0;
}

double bench_resident_mb(void) { return status_mb("VmRSS:"); }
double bench_peak_mb(void) { return status_mb("VmHWM:"); }

void bench_reset_peak(void) {
    FILE *f = fopen("/proc/self/clear_refs", "w");
    if (f) {
        fputs("5", f);
        fclose(f);
    }
}
