/* stats.c: means, nearest-rank percentiles and clocks for the benchmark. */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include "walk.h"

double stat_mean(const double *v, size_t n) {
  double s = 0;
  for (size_t i = 0; i < n; i++) s += v[i];
  return n ? s / (double)n : NAN;
}

static int cmp_double(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return (x > y) - (x < y);
}

double stat_pct(const double *v, size_t n, double q) {
  if (!n) return NAN;
  double *c = malloc(n * sizeof *c);
  if (!c) return NAN;
  memcpy(c, v, n * sizeof *c);
  qsort(c, n, sizeof *c, cmp_double);
  /* Nearest rank: the smallest value with at least q% of the values at or below it. */
  size_t r = (size_t)ceil(q / 100.0 * (double)n);
  double out = c[r ? r - 1 : 0];
  free(c);
  return out;
}

double stat_max(const double *v, size_t n) {
  double m = n ? v[0] : NAN;
  for (size_t i = 1; i < n; i++) m = v[i] > m ? v[i] : m;
  return m;
}

static double clock_ms(clockid_t id) {
  struct timespec ts;
  clock_gettime(id, &ts);
  return (double)ts.tv_sec * 1e3 + (double)ts.tv_nsec * 1e-6;
}

double now_ms(void) { return clock_ms(CLOCK_MONOTONIC); }
double cpu_ms(void) { return clock_ms(CLOCK_PROCESS_CPUTIME_ID); }
