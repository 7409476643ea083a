/* runs.h - repeated benchmark runs, each in a process of its own.
 *
 * On the 2-core machine the cost of fresh memory swings widely from one
 * minute to the next once a process holds more than the machine used
 * recently (bench_memory; the numbers are in docs/notes/base.md), and
 * pizza's erase fills much fresh memory after its load. A benchmark that
 * states a target therefore runs each case several times (-r), each in a
 * new process (so no run inherits another's heap), and sums the runs up as
 * a median, a range and how many met the target. */
#ifndef SC_BENCH_RUNS_H
#define SC_BENCH_RUNS_H

/* Runs fn(ud, out) in a child process; fn writes its measured seconds (one
 * double) to the descriptor `out` and returns 0 on success. *seconds gets
 * them. Returns 0 when the child succeeded and reported. */
int bench_in_child(int (*fn)(void *ud, int out), void *ud, double *seconds);

/* Writes one measured time to a descriptor given by bench_in_child. */
int bench_report_seconds(int out, double seconds);

/* "<name> <n> runs: <what> median ... s, range ...; target <= ... met in k of
 * n" (target 0: none); sorts seconds[0 .. n). Prints nothing when n < 2. */
void bench_summary(const char *name, const char *what, double *seconds, int n, double target);

/* This process's resident set now and its peak since the last
 * bench_reset_peak, in MiB (Linux /proc; -1 where unreadable). */
double bench_resident_mb(void);
double bench_peak_mb(void);
void bench_reset_peak(void);

#endif
