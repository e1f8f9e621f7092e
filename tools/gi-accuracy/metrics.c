/* metrics.c: relative MSE, mean relative error and bias per probe.
 *
 * Irradiance is compared by its luminance (Rec. 709 weights) per probe,
 * the figure a viewer sees; the floor keeps probes in near darkness from
 * turning a tiny absolute error into a huge relative one. A part the
 * reference reads as 0 at every probe has no relative error: NaN ("nan"
 * in the CSV and the report). */
#include "metrics.h"
#include <math.h>

static const float *part_of(const float *irr, const float *dir, const float *ind, acc_part p) {
  return p == ACC_DIRECT ? dir : p == ACC_INDIRECT ? ind : irr;
}

static double lum(const float c[3]) { return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]; }

static void compare(const float *const *x, const gi_ref_probe *ref, size_t n, acc_part p, acc_metrics *o) {
  double mean = 0;
  for (size_t i = 0; i < n; i++) mean += lum(part_of(ref[i].irradiance, ref[i].direct, ref[i].indirect, p)) / (double)n;
  double floor = fmax(0.01 * mean, 1e-30);
  double se_ = 0, ae = 0, rs = 0;
  o->ratio_min = INFINITY, o->ratio_max = -INFINITY, o->ratio_mean = 0;
  size_t nr = 0;
  for (size_t i = 0; i < n; i++) {
    double r = lum(part_of(ref[i].irradiance, ref[i].direct, ref[i].indirect, p));
    double s = lum(p == ACC_DIRECT ? ref[i].std_err_direct : p == ACC_INDIRECT ? ref[i].std_err_indirect
                                                                              : ref[i].std_err);
    double xv = lum(x[i]), d = fmax(r, floor), e = xv - r;
    se_ += e * e / (d * d);
    ae += fabs(e) / d;
    rs += s / d;
    if (r > floor) {
      double q = xv / r;
      o->ratio_mean += q, nr++;
      o->ratio_min = fmin(o->ratio_min, q), o->ratio_max = fmax(o->ratio_max, q);
    }
  }
  double m = (double)(n ? n : 1);
  o->rel_mse = se_ / m;
  o->mre = ae / m;
  /* Nothing to be relative to (a lone triangle's indirect light is 0 at
   * every probe): the errors are undefined, not 1e58. */
  if (!(mean > 1e-30)) o->rel_mse = o->mre = NAN;
  o->ref_rel_se = rs / m;
  if (nr) o->ratio_mean /= (double)nr;
  else o->ratio_mean = o->ratio_min = o->ratio_max = 1;
}

void acc_compare_probes(const gi_probe *got, const gi_ref_probe *ref, size_t n, acc_part p, acc_metrics *out) {
  const float *x[n ? n : 1];
  for (size_t i = 0; i < n; i++) x[i] = part_of(got[i].irradiance, got[i].direct, got[i].indirect, p);
  compare(x, ref, n, p, out);
}

void acc_compare_refs(const gi_ref_probe *got, const gi_ref_probe *ref, size_t n, acc_part p, acc_metrics *out) {
  const float *x[n ? n : 1];
  for (size_t i = 0; i < n; i++) x[i] = part_of(got[i].irradiance, got[i].direct, got[i].indirect, p);
  compare(x, ref, n, p, out);
}

void acc_pareto(const double *ms, const double *err, size_t n, int *on_front) {
  for (size_t i = 0; i < n; i++) {
    on_front[i] = 1;
    for (size_t j = 0; j < n && on_front[i]; j++)
      if (j != i && ms[j] <= ms[i] && err[j] <= err[i] && (ms[j] < ms[i] || err[j] < err[i])) on_front[i] = 0;
  }
}

double acc_ms_at_error(const double *ms, const double *mre, int n, double e, int *how) {
  *how = -1;
  for (int k = 0; k < n; k++) {
    if (!(mre[k] <= e)) continue;
    if (k == 0) {
      *how = 1;
      return ms[0];
    }
    *how = 0;
    double e0 = log(mre[k - 1]), e1 = log(mre[k]);
    /* Equal errors at both ends (or a zero error): take the later time. */
    if (!(e1 < e0) || !isfinite(e1)) return ms[k];
    double f = (log(e) - e0) / (e1 - e0);
    return exp(log(ms[k - 1]) + f * (log(ms[k]) - log(ms[k - 1])));
  }
  return n ? ms[n - 1] : 0;
}

double acc_crossover(double bake_ms, double answer_per_ms, double path_per_ms) {
  double gain = path_per_ms - answer_per_ms;
  if (!(gain > 0)) return INFINITY;
  if (!(bake_ms > 0)) return 1;
  /* Strictly cheaper: at count = bake / gain exactly, the two tie. */
  return floor(bake_ms / gain) + 1;
}
