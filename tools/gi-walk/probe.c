/* probe.c: the probe figures the benchmark compares (drift and popping). */
#include <math.h>
#include "walk.h"
#include "gi/gi_probe.h"

/* Below this share of the probe's largest figure a figure's relative
 * difference is taken against the floor (a dark direction has no scale). */
#define REL_FLOOR 1e-3

static const float AXES[6][3] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};

int probe_at(const gi_cascade *c, const double at[3], probe_figs *out, double *gather_ms) {
  gi_probe p;
  gi_error_info err = {0};
  if (gi_cascade_gather(c, at, 1, &p, gather_ms, &err) != GI_OK) {
    fprintf(stderr, "gi-walk: gather at %.3f %.3f %.3f: %s\n", at[0], at[1], at[2], err.msg);
    return -1;
  }
  out->v[0] = (p.sh[0][0] + p.sh[0][1] + p.sh[0][2]) / 3.0;
  for (int a = 0; a < 6; a++) {
    float e[3];
    gi_sh_eval_irradiance(p.sh, AXES[a], e);
    out->v[1 + a] = (e[0] + e[1] + e[2]) / 3.0;
  }
  return 0;
}

double probe_rel(const probe_figs *a, const probe_figs *b) {
  double big = 0, worst = 0;
  for (int k = 0; k < PROBE_FIGS; k++) big = fmax(big, fabs(b->v[k]));
  for (int k = 0; k < PROBE_FIGS; k++) {
    double scale = fmax(fabs(b->v[k]), REL_FLOOR * big);
    if (scale > 0) worst = fmax(worst, fabs(a->v[k] - b->v[k]) / scale);
  }
  return worst;
}
