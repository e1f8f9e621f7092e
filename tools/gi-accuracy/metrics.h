/* metrics.h: error of gathered irradiance against the reference.
 *
 * Plain functions over caller-owned arrays; no state, thread-safe. Used by
 * gi-accuracy and by the accuracy unit test (which compiles metrics.c in). */
#ifndef GI_ACC_METRICS_H
#define GI_ACC_METRICS_H

#include <stddef.h>
#include "gi/gi.h"

/* Which part of the irradiance to compare. */
typedef enum { ACC_TOTAL = 0, ACC_DIRECT = 1, ACC_INDIRECT = 2 } acc_part;

/* Error of one part over all probes, on luminance (Rec. 709). Relative
 * terms divide by max(ref, floor), floor = 1% of the mean reference of that
 * part, so a nearly dark probe does not dominate. ratio_* are per-probe
 * ratios (test / reference): the bias, 1 = unbiased. ref_rel_se
 * is the reference's own mean relative standard error over the probes. */
typedef struct acc_metrics {
  double rel_mse;      /* mean of (x - r)^2 / max(r, floor)^2; NaN when r is 0 at every probe */
  double mre;          /* mean of |x - r| / max(r, floor); NaN likewise */
  double ratio_mean, ratio_min, ratio_max;
  double ref_rel_se;
} acc_metrics;

/* Metrics of part p of the n probes got[i] (cone tracer) against ref[i]. */
void acc_compare_probes(const gi_probe *got, const gi_ref_probe *ref, size_t n, acc_part p, acc_metrics *out);
/* The same for path-traced probes (the sample-count sweep). */
void acc_compare_refs(const gi_ref_probe *got, const gi_ref_probe *ref, size_t n, acc_part p, acc_metrics *out);

/* Marks on_front[i] = 1 for the points (ms[i], err[i]) that no other point
 * beats in both time and error (ties keep both). */
void acc_pareto(const double *ms, const double *err, size_t n, int *on_front);

/* Path-tracer time at error e from a sweep of n increasing sample counts
 * (ms[k], mre[k]): log-log interpolation between the first count whose
 * error is at most e and the one before. *how: 0 interpolated; 1 the first
 * count is already at most e (returns its ms, an upper bound); -1 never
 * reached (returns the last ms, a lower bound; 0 when n is 0). */
double acc_ms_at_error(const double *ms, const double *mre, int n, double e, int *how);
/* How many queries one bake must serve before bake + answers beat the path
 * tracer: the smallest count with count * path_per > bake + count *
 * answer_per; INFINITY when the path tracer's query is no dearer than the
 * cone tracer's answer (it never wins), 1 when bake is 0. */
double acc_crossover(double bake_ms, double answer_per_ms, double path_per_ms);

#endif
